//! One SPH step, phenomena vs salva3d, same particles and support radius.
//!
//! `cargo bench -p phenomena-sph-peer` (this crate is outside the default members, so
//! plain builds and tests never compile salva3d). See `src/lib.rs` for what differs.
//! Each measured step starts from the same state: the block after one warm-up step
//! (which allocates each solver's buffers), rebuilt outside the timed region.

use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use phenomena_sph_peer::{block, ours, peer};
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("sph_step");
    g.sample_size(20).measurement_time(Duration::from_secs(10));
    let dt = 1.0 / 60.0;
    let gravity = Vector3::zeros();
    for n in [10_000usize, 30_000] {
        let points = block(n);
        let mut warm = ours(&points);
        warm.step().expect("step");
        g.bench_with_input(BenchmarkId::new("phenomena", points.len()), &n, |b, _| {
            b.iter_batched(|| warm.clone(), |mut sim| sim.step().expect("step"), BatchSize::PerIteration);
        });
        g.bench_with_input(BenchmarkId::new("salva3d_dfsph", points.len()), &n, |b, _| {
            b.iter_batched(
                || {
                    let mut world = peer(&points);
                    world.step(dt, &gravity);
                    world
                },
                |mut world| {
                    world.step(dt, &gravity);
                    world
                },
                BatchSize::PerIteration,
            );
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
