//! The starters and presets render well as written, at any size (issue 38): the sparkle
//! starter's diamond dust is not a white band at the horizon (its 10⁹ crystals in a
//! 100 m box dim with distance by default), and the paper flame's tip stays in frame.

use phenomena_scene::output::to_srgb8;
use phenomena_scene::{Assets, FrameSink, Output, Runner, Scene, SinkError, registry, shipped};
use serde_json::json;

/// The 8-bit sRGB image (interleaved) of frame `frame` of `scene` at `w × h`.
fn image(scene: &Scene, frame: u32, w: u32, h: u32) -> Vec<u8> {
    struct Keep(Vec<u8>);
    impl FrameSink for Keep {
        fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
            self.0 = to_srgb8(out.frame, &out.exposure);
            Ok(())
        }
    }
    let mut scene = scene.clone();
    let s = scene.settings_mut();
    (s.width, s.height) = (w, h);
    s.frames = s.frames.max(frame + 1);
    let mut runner = Runner::new(&scene, &Assets::none()).unwrap_or_else(|e| panic!("{e}"));
    let mut keep = Keep(Vec::new());
    runner.run(frame..frame + 1, &mut keep, &mut ()).unwrap_or_else(|e| panic!("{e}"));
    keep.0
}

/// Share of pixels white in all three channels (sRGB ≥ 240).
fn white_share(rgb: &[u8]) -> f64 {
    let white = rgb.chunks_exact(3).filter(|p| p.iter().all(|&c| c >= 240)).count();
    white as f64 / (rgb.len() / 3) as f64
}

/// The sparkle starter at two sizes: under 2 % of its pixels white (a glint covers a few
/// pixels; the band the paper's distance-independent brightness makes of 10⁹ crystals
/// covered a quarter of the frame, measured here with `falloff_from_m = 0` too).
#[test]
#[allow(clippy::print_stderr)] // the measures, for the notes (--nocapture)
fn the_sparkle_starter_is_no_white_band_at_any_size() {
    let entry = registry::phenomenon("sparkle").unwrap();
    let starter = phenomena_scene::parse(entry.starter(), "sparkle.toml").unwrap();
    let paper = starter.with_value("render.falloff_from_m", json!(0.0)).unwrap();
    for (w, h) in [(320, 180), (960, 540)] {
        let share = white_share(&image(&starter, 10, w, h));
        let band = white_share(&image(&paper, 10, w, h));
        eprintln!(
            "sparkle starter {w}x{h}: {:.2} % white; without the falloff {:.2} %",
            100.0 * share,
            100.0 * band
        );
        assert!(share < 0.02, "{w}x{h}: {:.2} % of the pixels white", 100.0 * share);
        assert!(band > 0.05, "{w}x{h}: the band without the falloff: {:.2} %", 100.0 * band);
    }
}

/// The top three rows' brightest 8-bit value and the frame's, for `scene` at 320x180.
fn top_and_max(scene: &Scene, frame: u32) -> (u8, u8) {
    let (w, h) = (320u32, 180u32);
    let rgb = image(scene, frame, w, h);
    let top = rgb[..(3 * w * 3) as usize].iter().copied().max().unwrap_or(0);
    (top, rgb.iter().copied().max().unwrap_or(0))
}

/// The paper flame (the defaults' camera) over black: nothing of the flame in the top
/// three rows of its frames (black is 0 in 8 bits; 2 allows for a splat's faintest
/// tail), where the camera before issue 38 cut the tip off.
#[test]
#[allow(clippy::print_stderr)] // the measures, for the notes (--nocapture)
fn the_paper_flame_stays_in_frame() {
    let paper = shipped::shipped("flame-paper").unwrap().scene().unwrap();
    let black = paper.with_value("render.background", json!({"kind": "black"})).unwrap();
    let old = black
        .with_value("render.camera.position", json!([0.0, 0.45, 2.2]))
        .and_then(|s| s.with_value("render.camera.look_at", json!([0.0, 0.45, 0.0])))
        .unwrap();
    let mut cut = 0;
    for frame in [60, 100, 120, 150, 179] {
        let (top, max) = top_and_max(&black, frame);
        let (old_top, _) = top_and_max(&old, frame);
        eprintln!("flame-paper frame {frame}: top rows {top} of {max}; with the old camera {old_top}");
        assert!(max > 100, "frame {frame}: a flame to see ({max})");
        assert!(top <= 2, "frame {frame}: the top rows reach {top} (the brightest pixel: {max})");
        cut += usize::from(old_top > 20);
    }
    assert!(cut >= 2, "the old camera cut the tip off in {cut} of the frames");
}
