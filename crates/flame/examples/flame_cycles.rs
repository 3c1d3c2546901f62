//! CPU time of flame steps and renders at 30,000 particles and 1280x720 with ½-res
//! splats, for comparing two builds on a busy machine, where
//! wall-clock benches drift:
//!
//!     cargo build --release -p phenomena-flame --example flame_cycles
//!     RAYON_NUM_THREADS=1 perf stat -e task-clock target/release/examples/flame_cycles 60
//!
//! (subtract a run with 0 frames: the warm-up). Prints a pixel sum and the particle
//! count, which two builds that should agree bit for bit must both print, and on
//! standard error the wall time per frame of the timed loop. A second argument `step`
//! or `render` times only that half (`render` renders the warmed-up state again and
//! again); `PAIRS=1` also prints each warm-up step's particles and neighbour pairs.
use glam::Vec3;
use phenomena_flame::{FlameConfig, FlameRenderer, FlameSim, RenderSettings};

#[allow(clippy::print_stdout, clippy::print_stderr, reason = "the pixel sum and the timings are the output")]
fn main() {
    let n = 30_000usize;
    // The bench's campfire (benches/flame.rs): 30,000 particles at steady state.
    let mut c = FlameConfig::default();
    c.emitter.lifetime_s = 1.0;
    c.emitter.rate_per_s = n as f32 / c.emitter.lifetime_s;
    c.emitter.radius_m = 0.08 * (n as f32 / 3000.0).sqrt();
    let mut sim = FlameSim::new(c, 1).expect("valid config");
    for _ in 0..120 {
        let st = sim.step().expect("step");
        if std::env::var("PAIRS").is_ok() {
            let per = st.neighbor_pairs as f64 / st.particles.max(1) as f64;
            eprintln!("{} particles, {} pairs, {per:.1} a particle", st.particles, st.neighbor_pairs);
        }
    }
    let mut s = RenderSettings { resolution_scale: 0.5, ..Default::default() };
    let scale = (n as f32 / 3000.0).sqrt().max(1.0);
    s.camera.position = Vec3::new(0.0, 0.45, 2.2 * scale.sqrt());
    let mut r = FlameRenderer::new(s, 1280, 720, None).expect("valid settings");
    let frames: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(10);
    let mut sum = 0.0f64;
    let only = std::env::args().nth(2).unwrap_or_default();
    let t0 = std::time::Instant::now();
    for _ in 0..frames {
        if only != "render" {
            sim.step().expect("step");
        }
        if only != "step" {
            let f = r.render(&sim);
            sum += f64::from(f.pixel(640, 400).x);
        }
    }
    eprintln!("{:.2} ms a frame", t0.elapsed().as_secs_f64() * 1e3 / frames.max(1) as f64);
    println!("{sum} {}", sim.particles().len());
}
