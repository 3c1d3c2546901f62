//! Snow that looks lit (issue 40): on every shipped snow scene's last frame, a share of
//! the scene lies in shadow (cast by the sun's shadow map, or a hollow the sky hardly
//! reaches) and shadowed snow is bluer than sunlit snow, as real snow under a blue sky
//! is. The measure is the issue's: pixels below 0.75 × the 90th percentile of the
//! scene's luminance are shadowed; at least 8 % of them must be.

use phenomena_scene::shipped::SHIPPED;
use phenomena_scene::snow::SnowScene;
use phenomena_snow::{Seen, SnowRenderer, SnowSim};

fn luminance(c: glam::Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

#[test]
#[allow(clippy::print_stderr)] // the measures, for the notes (--nocapture)
fn shipped_snow_scenes_have_blue_shadows() {
    for shipped in SHIPPED.iter().filter(|s| s.phenomenon == "snow") {
        let scene = shipped.scene().unwrap_or_else(|e| panic!("{e}"));
        let file = scene.get::<SnowScene>().expect("a snow scene");
        let builtin = file.geometry.builtin.expect("the shipped snow scenes use built-in meshes");
        let mut sim = SnowSim::new(builtin.mesh(), file.snow.clone(), file.scene.seed).expect("builds");
        for _ in 0..file.scene.frames {
            sim.step().expect("steps");
        }
        let (w, h) = (320, 180);
        let mut renderer = SnowRenderer::new(file.render.clone(), w, h, None).expect("renderer");
        let frame = renderer.render(&sim).clone();
        let seen = renderer.seen();
        let pixels: Vec<(glam::Vec3, Seen)> = (0..w * h)
            .filter(|&k| seen[k] != Seen::Background)
            .map(|k| (frame.pixel(k % w, k / w), seen[k]))
            .collect();
        let mut lum: Vec<f32> = pixels.iter().map(|p| luminance(p.0)).collect();
        lum.sort_by(f32::total_cmp);
        let p90 = lum[lum.len() * 9 / 10];
        let shadowed = lum.iter().filter(|&&l| l < 0.75 * p90).count();
        let share = shadowed as f64 / lum.len() as f64;
        // Blueness (B/R) of the snow in shadow and of the sunlit snow (at or above the
        // 90th percentile's 0.9).
        let blue = |keep: &dyn Fn(f32) -> bool| {
            let v: Vec<f64> = pixels
                .iter()
                .filter(|p| p.1 == Seen::Snow && keep(luminance(p.0)))
                .map(|p| f64::from(p.0.z / p.0.x.max(1e-6)))
                .collect();
            (v.iter().sum::<f64>() / v.len().max(1) as f64, v.len())
        };
        let (dark, n_dark) = blue(&|l| l < 0.75 * p90);
        let (lit, n_lit) = blue(&|l| l >= 0.9 * p90);
        eprintln!(
            "{}: {:.1} % of {} scene pixels shadowed; B/R shadowed snow {dark:.3} ({n_dark} px), sunlit {lit:.3} ({n_lit} px)",
            shipped.name,
            100.0 * share,
            lum.len()
        );
        assert!(share >= 0.08, "{}: {:.1} % shadowed", shipped.name, 100.0 * share);
        assert!(n_dark > 0 && n_lit > 0, "{}: snow both in shadow and in sun", shipped.name);
        // Measurably bluer: 10 % more blue per red than the sunlit snow.
        assert!(dark > 1.1 * lit, "{}: B/R {dark} in shadow vs {lit} in sun", shipped.name);
    }
}
