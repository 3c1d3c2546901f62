//! Splats and refraction footprints of any size may reach past the frame's edges: they
//! are clipped, never written out of bounds (a regression: a footprint wider than the
//! splat once indexed past the right edge).

use glam::Vec3;
use phenomena_flame::{FlameConfig, FlameRenderer, FlameSim, RenderSettings};

#[test]
fn footprints_past_the_edges_are_clipped() {
    let mut config = FlameConfig::default();
    config.wind.force_n_m3 = Vec3::new(3.0, 0.0, 0.0); // blow the flame off the right edge
    let mut sim = FlameSim::new(config, 8).unwrap();
    for _ in 0..60 {
        sim.step().unwrap();
    }
    for (scale, radius_scale, enabled, camera_x) in
        [(1.0, 3.0, true, 0.0), (0.5, 2.0, true, 0.0), (1.0, 4.0, false, -1.2), (0.5, 0.5, true, 1.0)]
    {
        let mut s = RenderSettings { resolution_scale: scale, ..Default::default() };
        s.shimmer.radius_scale = radius_scale;
        s.shimmer.enabled = enabled;
        s.camera.position.x = camera_x;
        s.camera.look_at.x = camera_x;
        let mut reused = FlameRenderer::new(s.clone(), 160, 90, None).unwrap();
        let mut last = Vec::new();
        for _ in 0..3 {
            sim.step().unwrap();
            last = reused.render(&sim).to_interleaved();
        }
        let fresh = FlameRenderer::new(s, 160, 90, None).unwrap().render(&sim).to_interleaved();
        assert!(last == fresh, "scale {scale}, radius_scale {radius_scale}: reused differs from fresh");
        assert!(last.iter().all(|v| v.is_finite()));
    }
}
