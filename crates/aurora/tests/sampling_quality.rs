//! Image-quality guard: any change to the physical mode's sampling
//! (fewer or better-placed emission points) must keep the frame as good. The measure is
//! the PSNR of a frame rendered with the default samples against a reference rendered
//! with 512 points per particle, over the linear RGB frame with the reference's
//! brightest value as the peak: PSNR = 10 log10(peak² / mean squared difference).
//!
//! The cases: thesis scene 2 after redistribution (frame 100), physical mode,
//! `SkySettings::thesis()`, seen by: the thesis's camera (38° up, 1280 × 720: the
//! guard's first case), the default ground camera (28° up) at the preview's 640 × 360,
//! the same thinned to every 5th and every 7th particle (the studio's preview,
//! `set_particle_subset`, thins 125,000 and 190,000 particles so), a close-up (8° field
//! of view), from orbit and the dome. The reference draws its offsets independently of
//! the frame (`set_sample_salt`), so its noise does not cancel the frame's. Rendering
//! is deterministic, so each PSNR is one exact number for the code; each floor is the
//! value measured when it was set less 0.2 dB, i.e. a change may not make a frame
//! measurably noisier (0.2 dB is 5 % more noise power).
//!
//! History. The thesis case (against 512 points with the frame's own offsets): 32
//! points with an independent offset per point (stratified jitter) 62.88 dB, the
//! guard's first value; 32 points with one offset per particle and line (systematic
//! sampling) 64.10 dB; 28 systematic points 62.98 dB (24: 61.71 dB).
//!
//! 2026-12-06, the floors reset with a change of sampling: the offsets of neighbouring
//! particles spread by a Weyl sequence in the store's cell order, and 14 points instead
//! of 28. Measured that day, 28 points with independent offsets (the reference sharing
//! the frame's offsets, as before) read 64.69 dB (thesis), 65.18 (ground at 1280 ×
//! 720), 66.12 (preview size), 55.56 / 53.89 (every 9th / 13th particle: the studio's
//! preview then, at 15,000 particles a frame), 32.59 (close-up), 90.08 (orbit) and
//! 81.99 dB (dome). With spread offsets against an independent reference, 28 points
//! read 72.23 (ground at 1280 × 720), 73.31, 33.40, 102.07 and 86.86 dB, and the new
//! default of 14 points reads the floors below: 66.17 (thesis), 66.73 (ground at 1280 ×
//! 720), 67.92, 57.87 / 55.84 (every 5th / 7th: the studio's preview now, at 30,000
//! particles a frame and about as many points as before; every 9th / 13th read 54.20 /
//! 51.80), 29.97, 96.76 and 80.51 dB. So half the points beat 28 independent ones where
//! many columns share a pixel (the shipped scenes' ground views); a close-up, where few
//! do, is 2.6 dB and the dome 1.5 dB noisier (16 points: 30.61 and 81.30 dB). That
//! trade was taken for the live preview (issue 41); a close-up wants
//! `points_per_particle` raised.
//!
//! 2026-12-06 (later), the floors raised with a change of allocation: a line that
//! emits gets at least one point instead of two, and the default is 15 points, which
//! the rounding makes 17 (1, 3, 11, 1, 1 against 2, 3, 10, 2, 2 = 19 before): 10 % fewer
//! points, and every view closer to the reference than with the 19: 66.56 (thesis),
//! 68.26 (preview size), 58.09 / 56.14 (every 5th / 7th), 30.28 (close-up), 96.79
//! (orbit) and 80.84 dB (dome), the values below. Measured the same day: at least one a
//! line with 14 (16 points) read 66.07, 67.80, 57.73, 55.72, 29.95, 96.43 (under the
//! orbit's old floor) and 80.42 dB; with 16 (18 points) 66.99, 68.69, 58.39, 56.50,
//! 30.59, 97.10 and 81.19 dB.

mod common;

use glam::Vec3;
use phenomena_aurora::{SkyCamera, SkyRenderer, SkySettings};
use phenomena_core::image::Frame;

/// PSNR of `frame` against `reference`, dB, peak = the reference's largest channel value.
fn psnr(frame: &Frame, reference: &Frame) -> f64 {
    psnr_of(|x, y| frame.pixel(x, y), reference)
}

/// [`psnr`] of the image whose pixel (x, y) is `pixel(x, y)`.
fn psnr_of(pixel: impl Fn(usize, usize) -> Vec3, reference: &Frame) -> f64 {
    let (w, h) = (reference.width(), reference.height());
    let (mut se, mut peak) = (0.0f64, 0.0f64);
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (pixel(x, y), reference.pixel(x, y));
            let d = a - b;
            se += f64::from(d.dot(d));
            peak = peak.max(f64::from(b.max_element()));
        }
    }
    let mse = se / (3 * w * h) as f64;
    10.0 * (peak * peak / mse).log10()
}

/// Points per particle of the reference frame.
const REFERENCE_POINTS: u32 = 512;

/// A view: name, camera, size, particle stride (`SkyRenderer::set_particle_subset`,
/// phase 0: the studio's thinned preview) and the PSNR measured (dB) when the floor was
/// set (2026-12-06, 15 points, at least one a line; see the history above).
struct View {
    name: &'static str,
    camera: SkyCamera,
    size: (usize, usize),
    stride: usize,
    measured_db: f64,
}

fn views() -> [View; 7] {
    let thesis = SkySettings::thesis().camera;
    let ground = SkyCamera::default();
    let close_up = SkyCamera::Ground { distance_km: 300.0, elevation_deg: 20.0, fov_y_deg: 8.0 };
    let orbit = SkyCamera::Orbit {
        altitude_km: 400.0,
        distance_km: 1000.0,
        look_at_altitude_km: 110.0,
        fov_y_deg: 60.0,
    };
    let dome = SkyCamera::Dome { fov_deg: 180.0 };
    let view = |name, camera, size, stride, measured_db| View { name, camera, size, stride, measured_db };
    [
        view("thesis", thesis, (1280, 720), 1, 66.56),
        view("ground, preview size", ground, (640, 360), 1, 68.26),
        view("ground, preview size, every 5th particle", ground, (640, 360), 5, 58.09),
        view("ground, preview size, every 7th particle", ground, (640, 360), 7, 56.14),
        view("close-up", close_up, (1280, 720), 1, 30.28),
        view("orbit", orbit, (1280, 720), 1, 96.79),
        view("dome", dome, (1024, 1024), 1, 80.84),
    ]
}

/// The frame of `view` with `points` a particle and the given salt, stride and phase 0.
fn render(
    sim: &phenomena_aurora::AuroraSim,
    view: &View,
    points_per_particle: u32,
    salt: u64,
    stride: usize,
) -> Frame {
    let settings = SkySettings { points_per_particle, camera: view.camera, ..SkySettings::thesis() };
    let mut sky = SkyRenderer::new(settings, view.size.0, view.size.1, None).expect("sky settings");
    sky.set_sample_salt(salt);
    sky.set_particle_subset(stride, 0);
    sky.render(sim).clone()
}

#[test]
#[ignore = "slow tier (100 frames, six renders with 512 points a particle): cargo test -- --include-ignored"]
#[allow(clippy::print_stderr, reason = "the measurement, for the record of a run")]
fn the_default_samples_stay_close_to_many_more() {
    let (config, _, seed) = common::load("aurora-scene2.toml");
    let sim = common::run(config, seed, 100);
    let default = SkySettings::thesis().points_per_particle;
    let mut low = Vec::new();
    let mut reference: Option<(&'static str, Frame)> = None;
    for view in views() {
        // The thinned views share the full preview's reference (the view before them).
        if view.stride == 1 || reference.is_none() {
            reference = Some((view.name, render(&sim, &view, REFERENCE_POINTS, 7, 1)));
        }
        let Some((_, reference)) = &reference else { unreachable!() };
        let db = psnr(&render(&sim, &view, default, 0, view.stride), reference);
        let (name, (w, h)) = (view.name, view.size);
        eprintln!(
            "scene 2, frame 100, {name}, {w}x{h}: PSNR of {default} points per particle against {REFERENCE_POINTS}: {db:.2} dB"
        );
        if db < view.measured_db - 0.2 {
            low.push(format!("{name}: {db:.2} dB, floor {:.2} dB", view.measured_db - 0.2));
        }
    }
    assert!(low.is_empty(), "noisier than the floor: {low:?}");
}

#[test]
#[ignore = "slow tier (100 frames and three renders, one with 512 points a particle)"]
fn a_salt_draws_other_samples_of_the_same_image() {
    // Two salts give different frames whose mean is closer to the 512-point reference
    // than either: independent noise around one expectation (the mean of two independent
    // estimates has half the noise power: +3 dB; a shared bias would cap the gain).
    let (config, _, seed) = common::load("aurora-scene2.toml");
    let sim = common::run(config, seed, 100);
    let camera = SkySettings::thesis().camera;
    let view = View { name: "thesis, preview size", camera, size: (640, 360), stride: 1, measured_db: 0.0 };
    let reference = render(&sim, &view, REFERENCE_POINTS, 7, 1);
    let default = SkySettings::thesis().points_per_particle;
    let (a, b) = (render(&sim, &view, default, 1, 1), render(&sim, &view, default, 2, 1));
    assert!(a != b, "two salts drew the same frame");
    let dm = psnr_of(|x, y| 0.5 * (a.pixel(x, y) + b.pixel(x, y)), &reference);
    let (da, db) = (psnr(&a, &reference), psnr(&b, &reference));
    // 3 dB less 0.5 dB for the reference's own noise and the two frames' differences.
    assert!(dm > da.max(db) + 2.5, "mean {dm:.2} dB, frames {da:.2} and {db:.2} dB");
}
