//! Checkpoints: writing and reading the state of thesis scene 2 after its
//! redistribution has grown it to about 190,000 particles (frame 100). Target: a state
//! within 10 MB, written within 100 ms.

use criterion::{Criterion, criterion_group, criterion_main};
use phenomena_scene::output::write_bytes_atomic;
use phenomena_scene::{Assets, Runner, Simulate};
use std::hint::black_box;
use std::path::Path;

/// The fixed reference workload reported beside these numbers.
#[path = "../../core/benches/shared/reference.rs"]
mod reference;

/// Keeps the last frame's counters.
struct Last(serde_json::Value);

impl phenomena_scene::Observer for Last {
    fn frame(&mut self, record: &phenomena_scene::FrameRecord) -> std::ops::ControlFlow<()> {
        self.0 = record.counters.clone();
        std::ops::ControlFlow::Continue(())
    }
}

#[allow(clippy::print_stderr)]
fn aurora(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/aurora-scene2.toml");
    let scene = phenomena_scene::load(&path).expect("scene 2");
    let mut runner = Runner::new(&scene, &Assets::none()).expect("builds");
    let mut last = Last(serde_json::Value::Null);
    runner.run(0..100, &mut Simulate, &mut last).expect("simulates");
    let bytes = runner.checkpoint().expect("encodes");
    eprintln!(
        "aurora-scene2 after 100 frames, {} particles: checkpoint of {} bytes ({:.2} MB)",
        last.0["particles"],
        bytes.len(),
        bytes.len() as f64 / 1e6
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("checkpoint_00100.ckpt");
    let mut group = c.benchmark_group("checkpoint");
    group.sample_size(20);
    group.bench_function("aurora_scene2_frame100_encode", |b| {
        b.iter(|| black_box(runner.checkpoint().expect("encodes")))
    });
    group.bench_function("aurora_scene2_frame100_write", |b| {
        b.iter(|| write_bytes_atomic(&file, &runner.checkpoint().expect("encodes")).expect("writes"))
    });
    group.bench_function("aurora_scene2_frame100_restore", |b| {
        b.iter(|| runner.restore(black_box(&bytes)).expect("restores"))
    });
    group.finish();
}

criterion_group!(benches, reference::reference, aurora);
criterion_main!(benches);
