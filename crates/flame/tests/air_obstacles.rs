//! The air's obstacles ([`phenomena_flame::air::Obstacle`]): a plate over the flame
//! stops it and spreads it sideways, as a ceiling does a fire's plume; no particle
//! enters a solid; a checkpoint beside one continues bit-identically. (In a wind:
//! `crates/scene/tests/gallery.rs`.)
use phenomena_flame::air::Obstacle;
use phenomena_flame::{FlameConfig, FlameSim};

/// The default burner (D = 0.16 m) with the air on and `obstacles`, after 1.5 s.
fn run(obstacles: Vec<Obstacle>) -> FlameSim {
    let mut c = FlameConfig::default();
    c.extended.air.enabled = true;
    c.extended.air.obstacles = obstacles;
    let mut sim = FlameSim::new(c, 5).expect("valid");
    for _ in 0..90 {
        sim.step().expect("step");
    }
    sim
}

/// A plate one burner diameter wide, two diameters above the burner, 2 cm thick.
fn plate() -> Obstacle {
    Obstacle { inner_radius_m: 0.0, outer_radius_m: 0.16, bottom_m: 0.32, top_m: 0.34 }
}

/// (particles within `band` m below the plate's underside, their mean distance from
/// the axis; particles above the plate's top within its radius).
fn around_the_plate(sim: &FlameSim) -> (usize, f32, usize) {
    let p = plate();
    let x = &sim.particles().position_m;
    let r = |v: &glam::Vec3| glam::Vec2::new(v.x, v.z).length();
    let under: Vec<f32> = x.iter().filter(|v| v.y > p.bottom_m - 0.08 && v.y < p.bottom_m).map(r).collect();
    let over = x.iter().filter(|v| v.y > p.top_m && r(v) < p.outer_radius_m).count();
    let mean = under.iter().sum::<f32>() / under.len().max(1) as f32;
    (under.len(), mean, over)
}

#[test]
fn a_plate_over_the_flame_spreads_it_and_holds_it_back() {
    let (open, covered) = (run(Vec::new()), run(vec![plate()]));
    let p = plate();
    let r = |v: &glam::Vec3| glam::Vec2::new(v.x, v.z).length();
    let inside = covered.particles().position_m.iter().filter(|v| p.contains(r(v), v.y)).count();
    assert_eq!(inside, 0, "particles inside the plate");
    let (n0, r0, over0) = around_the_plate(&open);
    let (n1, r1, over1) = around_the_plate(&covered);
    // Measured (seed 5): without the plate 101 particles in the band, 1.9 cm from the
    // axis on average, 1645 over the plate's disc; with it 448, 8.1 cm, 592. A plate as
    // wide as the plume turns it outwards beneath it (a ceiling jet) and lets through
    // only what rounds its rim: require twice the particles, twice as far out beneath
    // it, and under half as many above it.
    let report =
        format!("open: {n0} under at {r0:.3} m, {over0} over; plate: {n1} under at {r1:.3} m, {over1} over");
    assert!(n1 > 2 * n0 && r1 > 2.0 * r0, "{report}");
    assert!(2 * over1 < over0, "{report}");
}

#[test]
fn a_checkpoint_beside_an_obstacle_continues_bit_identically() {
    // The obstacles are static and the projection around them direct: a checkpoint
    // taken beside a plate continues bit-identically (nothing about them is saved).
    let mut c = FlameConfig::default();
    c.extended.air.enabled = true;
    c.extended.air.obstacles = vec![plate()];
    let mut a = FlameSim::new(c.clone(), 9).expect("valid");
    for _ in 0..30 {
        a.step().expect("step");
    }
    let mut b = FlameSim::new(c, 9).expect("valid");
    b.restore(a.state()).expect("restores");
    for _ in 0..20 {
        a.step().expect("step");
        b.step().expect("step");
    }
    assert_eq!(a.particles().position_m, b.particles().position_m);
}
