//! The renderer keeps its output frame between renders and rewrites only where the flame
//! was or is. A frame rendered after many others must equal the same frame rendered by a
//! fresh renderer: nothing of an earlier frame may linger.

use glam::Vec3;
use phenomena_flame::{FlameConfig, FlameRenderer, FlameSim, RenderSettings, WindKey};

#[test]
fn a_reused_renderer_leaves_no_trace_of_earlier_frames() {
    let mut config = FlameConfig::default();
    // Wind that swings the flame across the frame, so its footprint moves a lot.
    config.wind.keys = vec![
        WindKey { time_s: 0.0, force_n_m3: Vec3::new(-2.0, 0.0, 0.0) },
        WindKey { time_s: 0.5, force_n_m3: Vec3::new(2.0, 0.0, 0.0) },
        WindKey { time_s: 1.0, force_n_m3: Vec3::new(0.0, 0.0, 0.0) },
    ];
    let mut sim = FlameSim::new(config, 4).unwrap();
    for scale in [1.0, 0.5] {
        let settings = RenderSettings { resolution_scale: scale, ..Default::default() };
        let mut reused = FlameRenderer::new(settings.clone(), 160, 90, None).unwrap();
        for frame in 0..70 {
            sim.step().unwrap();
            let a = reused.render(&sim).to_interleaved();
            if frame % 10 == 9 {
                let b = FlameRenderer::new(settings.clone(), 160, 90, None)
                    .unwrap()
                    .render(&sim)
                    .to_interleaved();
                assert!(a == b, "frame {frame} at scale {scale} differs from a fresh render");
            }
        }
    }
}
