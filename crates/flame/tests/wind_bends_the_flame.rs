//! Figs 9 and 10 of the paper: wind to the left bends the flame left, wind to the right
//! bends it right. Measured on the rendered image, as a viewer would see it.

use glam::Vec3;
use phenomena_flame::{Background, FlameConfig, FlameRenderer, FlameSim, Mode, RenderSettings};

/// x of the luminance-weighted centroid of the flame (over black), in pixels.
fn bright_centroid_x(wind_x: f32) -> f32 {
    let mut config = FlameConfig { mode: Mode::Paper, ..Default::default() };
    config.wind.force_n_m3 = Vec3::new(wind_x, 0.0, 0.0);
    let mut sim = FlameSim::new(config, 11).unwrap();
    for _ in 0..90 {
        sim.step().unwrap();
    }
    let mut settings = RenderSettings { background: Background::Black, ..Default::default() };
    settings.shimmer.enabled = false;
    let (w, h) = (160, 90);
    let mut renderer = FlameRenderer::new(settings, w, h, None).unwrap();
    let frame = renderer.render(&sim);
    let lum = |x, y| f64::from(frame.pixel(x, y).dot(Vec3::new(0.2126, 0.7152, 0.0722)));
    let (mut sx, mut total) = (0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            sx += lum(x, y) * (x as f64 + 0.5);
            total += lum(x, y);
        }
    }
    assert!(total > 0.0, "the flame must be visible");
    (sx / total) as f32
}

#[test]
fn wind_moves_the_bright_centroid_with_it() {
    let left = bright_centroid_x(-0.6);
    let calm = bright_centroid_x(0.0);
    let right = bright_centroid_x(0.6);
    // The calm flame is centred (80 px of 160). A wind force of 0.6 N/m³ at a density
    // of about 1 kg/m³ accelerates the gas at a ≈ 0.6 m/s², displacing a particle of age
    // t by a·t²/2; averaged over lifetimes of 0.7-1.3 s (⟨t²⟩ ≈ 1/3 s²) and weighted
    // towards the young, dense gas, the light moves about 0.08 m, ≈ 5 px at the camera's
    // 65 px/m (measured: 6 px). Require half of that estimate.
    assert!((calm - 80.0).abs() < 2.0, "calm centroid {calm}");
    assert!(left < calm - 3.0, "left {left} vs calm {calm}");
    assert!(right > calm + 3.0, "right {right} vs calm {calm}");
}
