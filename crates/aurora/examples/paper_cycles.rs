//! CPU time of paper-mode frames (issue 23 item 2) at Table 3.2's 120,000 particles and
//! 1280x720, for comparing two builds on a busy machine, where wall-clock benches drift:
//!
//!     cargo build --release -p phenomena-aurora --example paper_cycles
//!     RAYON_NUM_THREADS=1 perf stat -e task-clock target/release/examples/paper_cycles 2
//!
//! (subtract a run with 0 frames: the set-up). Prints a pixel sum, which two builds that
//! should agree bit for bit must both print.
use phenomena_aurora::{AuroraConfig, AuroraSim, ColourMode, SkyRenderer, SkySettings};
#[allow(clippy::print_stdout, reason = "the pixel sum is the output")]
fn main() {
    let mut config = AuroraConfig::default();
    config.redistribution.enabled = false;
    let mut sim = AuroraSim::new(config, 1).expect("default aurora");
    for _ in 0..20 {
        sim.step().expect("step");
    }
    let settings = SkySettings { mode: ColourMode::Paper, ..SkySettings::default() };
    let mut sky = SkyRenderer::new(settings, 1280, 720, None).expect("sky");
    let frames: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(2);
    let mut sum = 0.0f64;
    for _ in 0..frames {
        let f = sky.render(&sim);
        sum += f64::from(f.pixel(640, 300).y);
    }
    println!("{sum}");
}
