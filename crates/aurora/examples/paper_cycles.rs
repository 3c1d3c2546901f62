//! CPU time of sky frames at Table 3.2's 120,000 particles and 1280x720 (the physical
//! and the paper mode), for comparing two builds on a busy machine, where wall-clock benches drift:
//!
//!     cargo build --release -p phenomena-aurora --example paper_cycles
//!     RAYON_NUM_THREADS=1 perf stat -e task-clock target/release/examples/paper_cycles 2
//!
//! (subtract a run with 0 frames: the set-up). The first argument is the number of
//! frames, the second the colour mode, `paper` (the default) or `physical`, the third
//! `each` for the paper mode's falls of each particle's own (`falls = "each"`). Prints a
//! pixel sum, which two builds that should agree bit for bit must both print, and on
//! standard error the wall time per frame and the renderer's last timings.
use phenomena_aurora::{AuroraConfig, AuroraSim, ColourMode, SkyRenderer, SkySettings};
use phenomena_core::clock::{Clock, SharedClock};

/// Wall time since the example started.
struct Wall(std::time::Instant);

impl Clock for Wall {
    fn now_ms(&self) -> f64 {
        self.0.elapsed().as_secs_f64() * 1e3
    }
}

#[allow(clippy::print_stdout, clippy::print_stderr, reason = "the pixel sum and the timings are the output")]
fn main() {
    let mut config = AuroraConfig::default();
    config.redistribution.enabled = false;
    let mut sim = AuroraSim::new(config, 1).expect("default aurora");
    for _ in 0..20 {
        sim.step().expect("step");
    }
    let mode = match std::env::args().nth(2).as_deref() {
        Some("physical") => ColourMode::Physical,
        _ => ColourMode::Paper,
    };
    let mut settings = SkySettings { mode, ..SkySettings::thesis() };
    if std::env::args().nth(3).as_deref() == Some("each") {
        settings.paper.falls = phenomena_aurora::fall::Falls::Each;
    }
    let mut sky = SkyRenderer::new(settings, 1280, 720, None).expect("sky");
    sky.set_clock(SharedClock::new(Wall(std::time::Instant::now())));
    let frames: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(2);
    let mut sum = 0.0f64;
    let t0 = std::time::Instant::now();
    for _ in 0..frames {
        let f = sky.render(&sim);
        sum += f64::from(f.pixel(640, 300).y);
    }
    let per = t0.elapsed().as_secs_f64() * 1e3 / frames.max(1) as f64;
    eprintln!("{per:.1} ms a frame; last frame {:?}", sky.timings());
    println!("{sum}");
}
