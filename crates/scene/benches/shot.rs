//! A shot of all four phenomena: `scenes/winter-night.toml` (the village under snow, an
//! aurora of 60,000 particles, diamond dust, a campfire) at the studio's preview size,
//! 640x360, after 100 frames: one frame simulated (every phenomenon stepped), and one
//! frame simulated and composed (every phenomenon drawn, pass by pass).

use criterion::{Criterion, criterion_group, criterion_main};
use phenomena_scene::{Assets, FrameSink, Output, Runner, Simulate, SinkError};
use std::path::Path;

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

fn winter_night(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/winter-night.toml");
    let mut scene = phenomena_scene::load(&path).expect("the shot");
    let s = scene.settings_mut();
    (s.width, s.height) = (640, 360);
    let mut runner = Runner::new(&scene, &Assets::beside(&path)).expect("builds");
    runner.run(0..100, &mut Simulate, &mut ()).expect("simulates");
    let mut group = c.benchmark_group("shot");
    group.sample_size(20);
    group.bench_function("winter_night_640x360_step", |b| {
        b.iter(|| {
            let at = runner.frames_done();
            runner.run(at..at + 1, &mut Simulate, &mut ()).expect("steps")
        })
    });
    group.bench_function("winter_night_640x360_step_render", |b| {
        b.iter(|| {
            let at = runner.frames_done();
            runner.run(at..at + 1, &mut Discard, &mut ()).expect("renders")
        })
    });
    group.finish();
}

criterion_group!(benches, reference::reference, winter_night);
criterion_main!(benches);
