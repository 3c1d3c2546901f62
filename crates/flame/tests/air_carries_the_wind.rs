//! With the air on, the wind still bends the flame (Figs 9, 10): it pushes the air,
//! whose column drifts downwind and carries the particles with it.
use glam::Vec3;
use phenomena_flame::{FlameConfig, FlameSim};

/// Mean x of the particles above one burner diameter after 1.5 s in a wind of
/// `wind_x` N/m³.
fn downwind(wind_x: f32) -> f32 {
    let mut c = FlameConfig::default();
    c.extended.air.enabled = true;
    c.wind.force_n_m3 = Vec3::new(wind_x, 0.0, 0.0);
    let d = 2.0 * c.emitter.radius_m;
    let mut sim = FlameSim::new(c, 5).expect("valid");
    for _ in 0..90 {
        sim.step().expect("step");
    }
    let p = sim.particles();
    let high: Vec<f32> = p.position_m.iter().filter(|x| x.y > d).map(|x| x.x).collect();
    assert!(high.len() > 100, "{} particles above one diameter", high.len());
    high.iter().sum::<f32>() / high.len() as f32
}

#[test]
fn the_wind_bends_the_flame_with_the_air() {
    let (left, calm, right) = (downwind(-0.6), downwind(0.0), downwind(0.6));
    // The wind accelerates the air at F/ρ = 0.6/1.2 = 0.5 m/s² for the time its gas
    // takes to rise, 0.6-1 s to a metre from a burner where it enters at 0.05 m/s: a
    // drift of a·t²/2 = 0.09-0.25 m at the top, less below. Measured 0.16 m; require
    // 0.05 m each way and a calm flame on the axis (within 1 cm of the burner's centre).
    assert!(calm.abs() < 0.01, "calm {calm} m");
    assert!(right > 0.05, "right {right} m");
    assert!(left < -0.05, "left {left} m");
    // The two winds mirror each other up to the random emission: within 30 %.
    assert!((left + right).abs() < 0.3 * right, "left {left} m, right {right} m");
}
