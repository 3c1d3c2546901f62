//! Core hot paths: neighbour-grid build and queries, separable blur, blackbody XYZ, VDB
//! encoding.
//!
//! Run with `cargo bench -p phenomena-core --bench core`.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use glam::Vec3;
use phenomena_core::color::{Observer, blackbody_xyz};
use phenomena_core::grid::NeighborGrid;
use phenomena_core::image::Plane;
use phenomena_core::rng::{Purpose, Stream};
use phenomena_core::vdb::{AnyGrid, Grid, GridClass, Metadata, Transform, encode_into};
use std::hint::black_box;

/// The fixed reference workload reported beside these numbers.
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

/// A thin curtain: a sheet 4 voxels thick waving through 2000 × 125 voxels (10^6 active
/// voxels, leaves about half full), with values varying by `seed`.
fn curtain(seed: f32) -> Grid<f32> {
    let transform = Transform::new(100.0, [0.0, 0.0, 100_000.0]).expect("transform");
    let mut g = Grid::new("emission_557_7nm", transform, GridClass::FogVolume);
    for x in 0..2000 {
        let z0 = (40.0 * (x as f32 / 100.0).sin()) as i32;
        for y in 0..125 {
            for z in z0..z0 + 4 {
                g.add([x, y, z], 1.0 + seed + (x + y + z) as f32 * 1e-3);
            }
        }
    }
    g
}

/// An aurora frame's grids: five float grids of 2 x 10^6 active voxels each (10^7 in
/// all), two curtains each.
fn aurora_lines() -> Vec<Grid<f32>> {
    let lines: Vec<Grid<f32>> = (0..5)
        .map(|k| {
            let mut a = curtain(k as f32);
            let b = curtain(k as f32 + 0.5);
            for (origin, values) in b.leaves() {
                let dst = a.leaf_mut([origin[0], origin[1] + 1000, origin[2]]);
                dst.copy_from_slice(values);
            }
            a
        })
        .collect();
    assert!(lines.iter().all(|l| l.active_voxel_count() == 2_000_000));
    lines
}

/// A flame frame's grids, at 1 cm: density, temperature and a vector emission.
struct FlameGrids {
    density: Grid<f32>,
    temperature: Grid<f32>,
    emission: Grid<[f32; 3]>,
}

impl FlameGrids {
    fn new() -> Self {
        let t = Transform::new(0.01, [0.0; 3]).expect("transform");
        Self {
            density: Grid::new("density", t, GridClass::FogVolume),
            temperature: Grid::new("temperature", t, GridClass::Unknown),
            emission: Grid::new("emission", t, GridClass::Unknown),
        }
    }

    /// Clear the grids and splat each particle (position m, temperature K) over the
    /// 3^3 voxels around it.
    fn splat(&mut self, particles: &[(Vec3, f32)]) {
        self.density.clear();
        self.temperature.clear();
        self.emission.clear();
        for &(p, kelvin) in particles {
            let c = (p / 0.01).round().as_ivec3();
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let w =
                            [1.0, 0.5, 1.0][(dx + 1) as usize] * [1.0, 0.5, 1.0][(dy + 1) as usize] * 0.125;
                        let ijk = [c.x + dx, c.y + dy, c.z + dz];
                        self.density.add(ijk, w);
                        self.temperature.add(ijk, w * kelvin);
                        self.emission.add(ijk, [w, 0.6 * w, 0.2 * w]);
                    }
                }
            }
        }
    }

    /// Encode the three grids into `out`; returns its length.
    fn encode(&self, out: &mut Vec<u8>) -> usize {
        let grids =
            [AnyGrid::from(&self.density), AnyGrid::from(&self.temperature), AnyGrid::from(&self.emission)];
        encode_into(&grids, &Metadata::new(), out);
        out.len()
    }
}

fn vdb(c: &mut Criterion) {
    let mut g = c.benchmark_group("vdb");
    g.sample_size(20);
    let mut out = Vec::new();

    // Encoding alone: one float grid of 10^6 active voxels.
    let sheet = curtain(0.0);
    assert_eq!(sheet.active_voxel_count(), 1_000_000);
    g.bench_function("encode_float_1e6", |b| {
        b.iter(|| {
            encode_into(&[AnyGrid::from(&sheet)], &Metadata::new(), &mut out);
            out.len()
        })
    });

    let lines = aurora_lines();
    let refs: Vec<AnyGrid<'_>> = lines.iter().map(AnyGrid::from).collect();
    g.bench_function("aurora_frame_5x2e6", |b| {
        b.iter(|| {
            encode_into(&refs, &Metadata::new(), &mut out);
            out.len()
        })
    });

    // A flame frame from scratch: 30,000 particles in 0.4 x 1.2 x 0.4 m splatted at 1 cm
    // over 3^3 voxels into density, temperature and a vector emission, then encoded.
    let mut s = Stream::new(1, Purpose::named("bench.vdb.flame"), 0);
    let particles: Vec<(Vec3, f32)> = (0..30_000)
        .map(|_| {
            (Vec3::new(s.next_f32() * 0.4, s.next_f32() * 1.2, s.next_f32() * 0.4), s.uniform(1200.0, 2000.0))
        })
        .collect();
    let mut flame = FlameGrids::new();
    g.bench_function("flame_frame_30k_particles", |b| {
        b.iter(|| {
            flame.splat(&particles);
            flame.encode(&mut out)
        })
    });
    // The encoding part of that frame alone.
    g.bench_function("flame_frame_encode_only", |b| b.iter(|| flame.encode(&mut out)));
    g.finish();
}

criterion_group!(benches, reference::reference, grid, blur, blackbody, srgb, vdb);
criterion_main!(benches);
