//! Core hot paths: neighbour-grid build and queries, separable blur, blackbody XYZ.
//!
//! Run with `cargo bench -p phenomena-core --bench core`.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use glam::Vec3;
use phenomena_core::color::{Observer, blackbody_xyz};
use phenomena_core::grid::NeighborGrid;
use phenomena_core::image::Plane;
use phenomena_core::rng::{Purpose, Stream};
use std::hint::black_box;

/// The fixed reference workload reported beside these numbers (issue 23).
#[path = "shared/reference.rs"]
mod reference;

fn cloud(n: usize) -> Vec<Vec3> {
    let mut s = Stream::new(1, Purpose::named("bench.cloud"), 0);
    (0..n).map(|_| Vec3::new(s.next_f32(), s.next_f32() * 2.0, s.next_f32()) * 0.6).collect()
}

fn grid(c: &mut Criterion) {
    let mut g = c.benchmark_group("grid");
    for n in [10_000usize, 30_000] {
        let points = cloud(n);
        let radius = 0.04;
        g.bench_with_input(BenchmarkId::new("build", n), &n, |b, _| {
            let mut grid = NeighborGrid::default();
            b.iter(|| grid.build(black_box(&points), radius).map(|()| grid.dims()));
        });
        let mut grid = NeighborGrid::default();
        grid.build(&points, radius).expect("finite points");
        g.bench_with_input(BenchmarkId::new("count_all_neighbours", n), &n, |b, _| {
            b.iter(|| {
                let mut pairs = 0usize;
                for &p in &points {
                    grid.for_each_candidate(p, |j| {
                        pairs += usize::from(points[j as usize].distance_squared(p) < radius * radius);
                    });
                }
                pairs
            });
        });
    }
    g.finish();
}

fn blur(c: &mut Criterion) {
    let mut plane = Plane::new(1280, 720);
    for i in 0..5000 {
        let f = i as f32;
        plane.deposit_nearest((f * 7.31) % 1280.0, (f * 3.77) % 720.0, 1.0);
    }
    c.bench_function("gaussian_blur_1280x720_sigma4", |b| {
        b.iter(|| {
            let mut p = plane.clone();
            p.gaussian_blur(4.0);
            p
        })
    });
}

fn blackbody(c: &mut Criterion) {
    c.bench_function("blackbody_xyz_cie1931", |b| {
        b.iter(|| blackbody_xyz(Observer::Cie1931TwoDegree, black_box(1900.0)))
    });
}

fn srgb(c: &mut Criterion) {
    // One 640×360 RGB frame of values spread over the encoder's range (the studio's
    // per-frame tone map): the direct encoder against the table one.
    let values: Vec<f32> = (0..640 * 360 * 3).map(|i| ((i * 7919) % 100_003) as f32 / 90_000.0).collect();
    let mut g = c.benchmark_group("srgb_encode_u8_640x360x3");
    g.bench_function("direct", |b| {
        b.iter(|| values.iter().map(|&v| u32::from(phenomena_core::color::srgb_encode_u8(v))).sum::<u32>())
    });
    g.bench_function("fast", |b| {
        b.iter(|| {
            values.iter().map(|&v| u32::from(phenomena_core::color::srgb_encode_u8_fast(v))).sum::<u32>()
        })
    });
    g.finish();
}

criterion_group!(benches, reference::reference, grid, blur, blackbody, srgb);
criterion_main!(benches);
