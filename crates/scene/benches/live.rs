//! Issue 41's live target: every shipped scene stepped and rendered at the studio's
//! preview size, 640x360, around its middle frame (what a user scrubbing the timeline
//! sees), one benchmark per scene (`live/<scene>`), beside the reference workload.
//!
//! Before a scene's benchmark, twelve frames from the middle are timed with a wall clock
//! through the runner's records and one line goes to stderr: the particles, the median
//! step and render, their shares (where a scene steps its next frame beside the render,
//! that step's time within the render), the reference chain timed just before and after those
//! frames (and the sum in chains, and at a quiet day's chain), and the renderer's own
//! breakdown where it has one (the aurora: emission, deposit, ...). Run one scene with
//! `cargo bench -p phenomena-scene --bench live -- aurora-scene2`.

use std::path::Path;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use phenomena_core::clock::{Clock, SharedClock};
use phenomena_scene::shipped::SHIPPED;
use phenomena_scene::{Assets, FrameRecord, FrameSink, Observer, Output, Runner, Simulate, SinkError};

/// The fixed reference workload reported beside these numbers.
#[path = "../../core/benches/shared/reference.rs"]
mod reference;

/// Takes every frame's image and drops it.
struct Discard;

impl FrameSink for Discard {
    fn write(&mut self, _output: &Output<'_>) -> Result<(), SinkError> {
        Ok(())
    }
}

/// The wall clock, for the records' timings.
struct Wall(Instant);

impl Clock for Wall {
    fn now_ms(&self) -> f64 {
        self.0.elapsed().as_secs_f64() * 1e3
    }
}

/// Keeps every frame's record.
#[derive(Default)]
struct Records(Vec<FrameRecord>);

impl Observer for Records {
    fn frame(&mut self, record: &FrameRecord) -> std::ops::ControlFlow<()> {
        self.0.push(record.clone());
        std::ops::ControlFlow::Continue(())
    }
}

/// `reference/chain_2e22` on a quiet day of this machine (criterion's median,
/// 2026-12-06 17:16, docs/performance.md): the scale of each scene's sum in chains is
/// read back in ms at that speed (a compute-bound estimate of the quiet machine, not a
/// measurement of it).
const QUIET_CHAIN_MS: f64 = 35.59;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() { 0.0 } else { v[v.len() / 2] }
}

/// A shipped scene at 640x360, simulated to six frames before its middle, after twelve
/// frames timed and reported.
#[allow(clippy::print_stderr)]
fn ready(name: &str) -> Runner {
    let shipped = SHIPPED.iter().find(|s| s.name == name).expect("a shipped scene");
    let mut scene = shipped.scene().expect("parses");
    let s = scene.settings_mut();
    (s.width, s.height) = (640, 360);
    let middle = (s.frames / 2).saturating_sub(6);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/x.toml");
    let mut runner = Runner::new(&scene, &Assets::beside(&dir)).expect("builds");
    runner.run(0..middle, &mut Simulate, &mut ()).expect("simulates");
    runner.set_clock(SharedClock::new(Wall(Instant::now())));
    let mut records = Records::default();
    let before = reference::chain_ms_now(3);
    runner.run(middle..middle + 12, &mut Discard, &mut records).expect("renders");
    let after = reference::chain_ms_now(3);
    let step = median(records.0.iter().map(|r| r.step_ms).collect());
    let render = median(records.0.iter().map(|r| r.render_ms.unwrap_or(0.0)).collect());
    // A step taken beside the render (the snow's): within `render`.
    let aheads: Vec<f64> = records.0.iter().filter_map(|r| r.ahead_ms).collect();
    let ahead = if aheads.is_empty() {
        String::new()
    } else {
        format!(", the next frame's step {:.1} ms of it taken beside the render", median(aheads))
    };
    let last = records.0.last().expect("twelve records");
    let particles = last.counters.get("particles").map_or("-".to_string(), ToString::to_string);
    let total = step + render;
    // The chain read just before and after these frames: the load they ran under.
    let chain = 0.5 * (before + after);
    eprintln!(
        "live {name}: {particles} particles; median step {step:.1} ms ({:.0} %), render {render:.1} ms ({:.0} %{ahead}), sum {total:.1} ms; reference chain_2e22 {before:.1} ms before, {after:.1} after: sum {:.2} chains, {:.1} ms at the quiet day's chain ({QUIET_CHAIN_MS} ms); render detail {}",
        100.0 * step / total.max(1e-9),
        100.0 * render / total.max(1e-9),
        total / chain,
        total / chain * QUIET_CHAIN_MS,
        last.render_detail.as_ref().map_or("-".to_string(), ToString::to_string)
    );
    runner.set_clock(SharedClock::default());
    runner
}

fn live(c: &mut Criterion) {
    let mut group = c.benchmark_group("live");
    group.sample_size(10);
    for shipped in SHIPPED.iter() {
        let mut runner: Option<Runner> = None;
        group.bench_function(shipped.name, |b| {
            let runner = runner.get_or_insert_with(|| ready(shipped.name));
            b.iter(|| {
                let at = runner.frames_done();
                runner.run(at..at + 1, &mut Discard, &mut ()).expect("renders")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, reference::reference, live);
criterion_main!(benches);
