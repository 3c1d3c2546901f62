//! Flickering and pulsating aurora measured from rendered frames of the shipped scenes
//! (issue 39): flickering patches' brightness spectra peak within the observed 7-13 Hz;
//! pulsating patches have periods within 2-20 s, swing by at least half their
//! brightness, and are not in phase with each other.
//!
//! The frames are the scenes' own (their camera, particles, frame time), at a small size,
//! with the night around the aurora (stars, airglow, Milky Way, ground) switched off: that light is
//! constant and added to the aurora's, so it changes no spectrum, but it would count in
//! a patch's brightness when its swing is measured.

use phenomena_core::image::Frame;
use phenomena_scene::{Assets, FrameSink, Output, Runner, Scene, SinkError, shipped};
use serde_json::json;

/// Mean luminance of each `tile`×`tile` block of every frame of `name` at `w × h`:
/// `series[k][f]` for tile k and frame f.
fn tile_series(name: &str, w: u32, h: u32, tile: usize) -> (Vec<Vec<f64>>, f64) {
    struct Tiles {
        tile: usize,
        series: Vec<Vec<f64>>,
    }
    impl FrameSink for Tiles {
        fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
            let means = tile_means(out.frame, self.tile);
            self.series.resize(means.len(), Vec::new());
            for (s, m) in self.series.iter_mut().zip(means) {
                s.push(m);
            }
            Ok(())
        }
    }
    let mut scene: Scene = shipped::shipped(name).expect("shipped").scene().unwrap_or_else(|e| panic!("{e}"));
    for key in ["stars", "airglow", "milky_way", "ground"] {
        scene = scene.with_value(&format!("render.sky.{key}"), json!(false)).expect("a sky setting");
    }
    let s = scene.settings_mut();
    (s.width, s.height) = (w, h);
    let frames = s.frames;
    let frame_time = scene.frame_time_s();
    let mut runner = Runner::new(&scene, &Assets::none()).unwrap_or_else(|e| panic!("{e}"));
    let mut tiles = Tiles { tile, series: Vec::new() };
    runner.run(0..frames, &mut tiles, &mut ()).unwrap_or_else(|e| panic!("{e}"));
    (tiles.series, frame_time)
}

/// Rec. 709 luminance of each block, row by row.
fn tile_means(frame: &Frame, tile: usize) -> Vec<f64> {
    let (tx, ty) = (frame.width() / tile, frame.height() / tile);
    let mut out = vec![0.0; tx * ty];
    for y in 0..ty * tile {
        for x in 0..tx * tile {
            let p = frame.pixel(x, y);
            let l = 0.2126 * f64::from(p.x) + 0.7152 * f64::from(p.y) + 0.0722 * f64::from(p.z);
            out[(y / tile) * tx + x / tile] += l / (tile * tile) as f64;
        }
    }
    out
}

/// Power of `series` (sampled every `dt` s, mean removed, Hann window) at `hz`.
fn power_at(series: &[f64], dt: f64, hz: f64) -> f64 {
    let n = series.len();
    let mean = series.iter().sum::<f64>() / n as f64;
    let (mut c, mut s) = (0.0, 0.0);
    for (i, v) in series.iter().enumerate() {
        let window = 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / (n - 1) as f64).cos();
        let phase = std::f64::consts::TAU * hz * i as f64 * dt;
        c += (v - mean) * window * phase.cos();
        s += (v - mean) * window * phase.sin();
    }
    c * c + s * s
}

/// Frequency of the largest power over `lo..hi` Hz in steps of `step`.
fn peak_hz(series: &[f64], dt: f64, lo: f64, hi: f64, step: f64) -> f64 {
    let n = ((hi - lo) / step).round() as usize;
    (0..=n)
        .map(|k| lo + step * k as f64)
        .max_by(|&a, &b| power_at(series, dt, a).total_cmp(&power_at(series, dt, b)))
        .unwrap()
}

/// `s` minus its centred moving average over `n` samples (a high-pass filter: what
/// changes faster than about 1/(n dt) Hz); the ends, where the window does not fit,
/// are left out.
fn high_pass(s: &[f64], n: usize) -> Vec<f64> {
    let half = n / 2;
    (half..s.len() - half)
        .map(|i| s[i] - s[i - half..=i + half].iter().sum::<f64>() / (2 * half + 1) as f64)
        .collect()
}

/// `s` minus its least-squares straight line (a slow drift of the whole display).
fn detrend(s: &[f64]) -> Vec<f64> {
    let n = s.len() as f64;
    let (mx, my) = ((n - 1.0) / 2.0, s.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, y) in s.iter().enumerate() {
        sxy += (i as f64 - mx) * (y - my);
        sxx += (i as f64 - mx) * (i as f64 - mx);
    }
    let slope = sxy / sxx;
    s.iter().enumerate().map(|(i, y)| y - my - slope * (i as f64 - mx)).collect()
}

fn std_dev(s: &[f64]) -> f64 {
    let m = s.iter().sum::<f64>() / s.len() as f64;
    (s.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / s.len() as f64).sqrt()
}

fn percentile(s: &[f64], q: f64) -> f64 {
    let mut v = s.to_vec();
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let (ma, mb) = (a.iter().sum::<f64>() / a.len() as f64, b.iter().sum::<f64>() / b.len() as f64);
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        ab += (x - ma) * (y - mb);
        aa += (x - ma) * (x - ma);
        bb += (y - mb) * (y - mb);
    }
    ab / (aa * bb).sqrt().max(1e-30)
}

/// The flicker scene at 160x90 (4 s at 60 frames a second). A tile's brightness also
/// changes slowly as the arc moves across it (its curls, rays and bend: most of the
/// variance of tiles on the arc's edges, below 1 Hz); as in analyses of high-speed
/// imaging, that is removed first by subtracting a 0.35 s moving average (21 frames),
/// which keeps what changes faster than about 3 Hz. The 20 lit tiles with the most of
/// that fast variance (relative to their mean) are the flickering patches; each one's
/// spectrum, from 0.5 Hz to the 30 Hz Nyquist frequency in 0.25 Hz steps (the 4 s
/// record's resolution), peaks within 7-13 Hz, not at the filter's edge nor above.
#[test]
#[ignore = "slow: renders 240 frames of a shipped scene (about 10 s optimised)"]
#[allow(clippy::print_stderr)] // the measures, for the notes (--nocapture)
fn flickering_patches_peak_within_7_to_13_hz() {
    let (series, dt) = tile_series("aurora-flicker", 160, 90, 4);
    assert!((dt - 1.0 / 60.0).abs() < 1e-4, "the scene's frame time {dt}");
    let brightest = series.iter().map(|s| s.iter().sum::<f64>() / s.len() as f64).fold(0.0, f64::max);
    let mut lit: Vec<&Vec<f64>> =
        series.iter().filter(|s| s.iter().sum::<f64>() / s.len() as f64 > 0.1 * brightest).collect();
    assert!(lit.len() > 40, "{} lit tiles", lit.len());
    let relative = |s: &[f64]| std_dev(&high_pass(s, 21)) / (s.iter().sum::<f64>() / s.len() as f64);
    lit.sort_by(|a, b| relative(b).total_cmp(&relative(a)));
    let peaks: Vec<f64> = lit[..20].iter().map(|s| peak_hz(&high_pass(s, 21), dt, 0.5, 30.0, 0.25)).collect();
    let swings: Vec<f64> = lit[..20].iter().map(|s| relative(s)).collect();
    eprintln!("flicker: peaks {peaks:?} Hz; relative std {swings:.2?}");
    for (k, f) in peaks.iter().enumerate() {
        assert!((7.0..=13.0).contains(f), "tile {k} of the 20 most flickering peaks at {f} Hz");
    }
}

/// The pulsating scene at 128x72 (40 s at 30 frames a second): of the tiles inside the
/// diffuse aurora (some of its light there at all times: p5 ≥ 2 % of p95; at the band's
/// edges the drifting band itself moves in and out), the 10 brightest when on (95th
/// percentile) are the patches; each swings by at least half its
/// brightness ((p95 − p5)/p95 ≥ 0.5); its spectrum's peak over periods of 1.5-40 s,
/// after removing the straight line that the band's slow drift over the tile makes,
/// lies within 2-20 s; and at least three of them are not in phase (pairwise
/// correlation under 0.5, chosen greedily from the brightest).
#[test]
#[ignore = "slow: renders 1200 frames of a shipped scene (about a minute optimised)"]
#[allow(clippy::print_stderr)] // the measures, for the notes (--nocapture)
fn pulsating_patches_switch_with_their_own_periods_of_2_to_20_s() {
    let (series, dt) = tile_series("aurora-pulsating", 128, 72, 8);
    assert!(series[0].len() as f64 * dt >= 30.0, "the scene lasts {} s", series[0].len() as f64 * dt);
    let mut tiles: Vec<&Vec<f64>> =
        series.iter().filter(|s| percentile(s, 0.05) >= 0.02 * percentile(s, 0.95)).collect();
    assert!(tiles.len() >= 10, "{} tiles inside the aurora", tiles.len());
    tiles.sort_by(|a, b| percentile(b, 0.95).total_cmp(&percentile(a, 0.95)));
    let patches = &tiles[..10];
    let mut independent: Vec<&Vec<f64>> = Vec::new();
    for (k, s) in patches.iter().enumerate() {
        let (hi, lo) = (percentile(s, 0.95), percentile(s, 0.05));
        let swing = (hi - lo) / hi;
        // Frequencies 1/40 to 1/1.5 Hz in steps of 1/400 Hz (a tenth of the record's
        // resolution, 1/40 Hz).
        let hz = peak_hz(&detrend(s), dt, 1.0 / 40.0, 1.0 / 1.5, 0.0025);
        eprintln!("pulsating tile {k}: swing {swing:.2}, period {:.2} s", 1.0 / hz);
        assert!(swing >= 0.5, "tile {k} swings by {swing:.2} of its brightness");
        assert!((2.0..=20.0).contains(&(1.0 / hz)), "tile {k} pulsates with a period of {} s", 1.0 / hz);
        if independent.iter().all(|o| correlation(s, o).abs() < 0.5) {
            independent.push(s);
        }
    }
    assert!(independent.len() >= 3, "only {} of the patches pulsate out of phase", independent.len());
}
