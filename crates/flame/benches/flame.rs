//! Flame hot paths: one SPH step, one 1280×720 render (splats, shimmer, composite), and
//! the two together, at 10,000 and 30,000 particles and the
//! paper's 3,000.
//!
//! Also one OpenVDB frame of 30,000 particles (`flame_vdb`), and the 30,000-particle
//! flame with the air around it (`flame_air`).
//!
//! Run with `cargo bench -p phenomena-flame --bench flame`. The flame is the campfire-like
//! configuration below, warmed up until its particle count is steady.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use glam::Vec3;
use phenomena_flame::{FlameConfig, FlameRenderer, FlameSim, RenderSettings};
use std::hint::black_box;
use std::time::Duration;

/// The fixed reference workload reported beside these numbers.
#[path = "../../core/benches/shared/reference.rs"]
mod reference;

/// A flame whose steady state holds about `n` particles (rate × mean lifetime).
fn config(n: usize) -> FlameConfig {
    let mut c = FlameConfig::default();
    c.emitter.lifetime_s = 1.0;
    c.emitter.rate_per_s = n as f32 / c.emitter.lifetime_s;
    // Keep the emission density (and so the neighbour count) the same at every n: the
    // burner area grows with the rate.
    c.emitter.radius_m = 0.08 * (n as f32 / 3000.0).sqrt();
    c
}

fn warm(n: usize) -> FlameSim {
    let mut sim = FlameSim::new(config(n), 1).expect("valid config");
    for _ in 0..120 {
        sim.step().expect("step");
    }
    sim
}

fn renderer(n: usize, resolution_scale: f32) -> FlameRenderer {
    let mut s = RenderSettings { resolution_scale, ..Default::default() };
    // Frame the wider burner of the larger flames.
    let scale = (n as f32 / 3000.0).sqrt().max(1.0);
    s.camera.position = Vec3::new(0.0, 0.45, 2.2 * scale.sqrt());
    FlameRenderer::new(s, 1280, 720, None).expect("valid settings")
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("flame");
    g.sample_size(20).measurement_time(Duration::from_secs(6)).warm_up_time(Duration::from_secs(2));
    for n in [3_000usize, 10_000, 30_000] {
        let sim = warm(n);
        assert!(sim.particles().len() > n * 9 / 10, "warm-up reaches about {n} particles");
        g.bench_with_input(BenchmarkId::new("step", n), &n, |b, _| {
            let mut s = sim.clone();
            b.iter(|| black_box(s.step().expect("step")));
        });
        for scale in [1.0f32, 0.5] {
            // An animation renders into the renderer's own frame, reused every frame.
            let mut r = renderer(n, scale);
            g.bench_with_input(BenchmarkId::new(format!("render_1280x720_scale{scale}"), n), &n, |b, _| {
                b.iter(|| black_box(r.render(&sim).width()));
            });
            let mut r = renderer(n, scale);
            g.bench_with_input(
                BenchmarkId::new(format!("step_render_1280x720_scale{scale}"), n),
                &n,
                |b, _| {
                    let mut s = sim.clone();
                    b.iter(|| {
                        s.step().expect("step");
                        black_box(r.render(&s).width())
                    });
                },
            );
        }
    }
    g.finish();
}

/// The air around the flame (`[flame.extended.air]`, issue 43): one step of the
/// 30,000-particle flame with the air on (D = 0.51 m), and the air's own share: one
/// frame of the air alone over the same burner.
fn air(c: &mut Criterion) {
    let n = 30_000;
    let mut cfg = config(n);
    cfg.extended.air.enabled = true;
    let mut sim = FlameSim::new(cfg.clone(), 1).expect("valid config");
    for _ in 0..120 {
        sim.step().expect("step");
    }
    let mut g = c.benchmark_group("flame_air");
    g.sample_size(10).measurement_time(Duration::from_secs(8)).warm_up_time(Duration::from_secs(2));
    g.bench_with_input(BenchmarkId::new("step", n), &n, |b, _| {
        let mut s = sim.clone();
        b.iter(|| black_box(s.step().expect("step")));
    });
    let mut r = renderer(n, 0.5);
    g.bench_with_input(BenchmarkId::new("step_render_1280x720_scale0.5", n), &n, |b, _| {
        let mut s = sim.clone();
        b.iter(|| {
            s.step().expect("step");
            black_box(r.render(&s).width())
        });
    });
    let air = sim.air().expect("the air is on").clone();
    g.bench_function("air_alone_frame", |b| {
        let mut a = air.clone();
        b.iter(|| {
            a.step(cfg.frame_time_s, Vec3::ZERO);
            black_box(a.grid().max_speed())
        });
    });
    g.finish();
}

/// Target: one VDB frame of 30,000 particles at 1 cm voxels (voxelising the
/// three grids and encoding the file) within 50 ms. `frame_*` is a frame of an animation
/// as the VDB sink writes it (the voxeliser's grids and the file buffer kept from the
/// previous frame); `voxelize_*` and `encode_*` are its two halves; `first_frame_*`
/// allocates everything afresh, as the first frame of a render does.
fn volume(c: &mut Criterion) {
    use phenomena_core::vdb::{AnyGrid, Metadata, encode, encode_into};
    use phenomena_flame::volume::{Voxelizer, voxelize};
    let sim = warm(30_000);
    let r = renderer(30_000, 0.5);
    let mut g = c.benchmark_group("flame_vdb");
    g.sample_size(20);
    let mut voxelizer = Voxelizer::default();
    let mut file = Vec::new();
    g.bench_function("frame_30000_particles_1cm", |b| {
        b.iter(|| {
            let v = voxelizer
                .voxelize(sim.particles(), sim.config(), r.settings(), r.lut(), 0.01)
                .expect("voxelises");
            let grids =
                [AnyGrid::from(&v.density), AnyGrid::from(&v.temperature), AnyGrid::from(&v.emission)];
            encode_into(&grids, &Metadata::new(), &mut file);
            black_box(file.len())
        });
    });
    g.bench_function("voxelize_30000_particles_1cm", |b| {
        b.iter(|| {
            let v = voxelizer
                .voxelize(sim.particles(), sim.config(), r.settings(), r.lut(), 0.01)
                .expect("voxelises");
            black_box(v.density.active_voxel_count())
        });
    });
    let v = voxelize(sim.particles(), sim.config(), r.settings(), r.lut(), 0.01).expect("voxelises");
    g.bench_function("encode_30000_particles_1cm", |b| {
        b.iter(|| {
            let grids =
                [AnyGrid::from(&v.density), AnyGrid::from(&v.temperature), AnyGrid::from(&v.emission)];
            encode_into(&grids, &Metadata::new(), &mut file);
            black_box(file.len())
        });
    });
    g.bench_function("first_frame_30000_particles_1cm", |b| {
        b.iter(|| {
            let v = voxelize(sim.particles(), sim.config(), r.settings(), r.lut(), 0.01).expect("voxelises");
            let grids =
                [AnyGrid::from(&v.density), AnyGrid::from(&v.temperature), AnyGrid::from(&v.emission)];
            black_box(encode(&grids, &Metadata::new()).len())
        });
    });
    g.finish();
}

criterion_group!(benches, reference::reference, bench, volume, air);
criterion_main!(benches);
