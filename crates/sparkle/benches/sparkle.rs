//! Sparkle hot paths (its speed targets): one frame (step + 1280×720 render) of
//! 10⁹ virtual diamond-dust crystals with n = 10,000 (visible fraction 3.0·10⁻⁴), and a
//! step of the stochastic model against a brute-force step at equal N = 10⁷.
//!
//! Run with `cargo bench -p phenomena-sparkle --bench sparkle`; compare the two `step/`
//! lines of one run for the speed ratio (the machine is shared: ratios within a run).

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use phenomena_sparkle::{Method, Population, RenderSettings, SparkleConfig, SparkleRenderer, SparkleSim};
use std::hint::black_box;
use std::time::Duration;

/// The fixed reference workload reported beside these numbers.
#[path = "../../core/benches/shared/reference.rs"]
mod reference;

fn config(method: Method, virtual_count: f64) -> SparkleConfig {
    let mut c = SparkleConfig { method, ..SparkleConfig::default() };
    if let Population::DiamondDust(d) = &mut c.population {
        let v = (d.box_max_m - d.box_min_m).as_dvec3();
        d.density_per_m3 = virtual_count / (v.x * v.y * v.z);
    }
    c
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("frame");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    let mut sim = SparkleSim::new(config(Method::Stochastic, 1e9), 1).expect("valid");
    let mut renderer = SparkleRenderer::new(RenderSettings::default(), 1280, 720, None).expect("valid");
    g.bench_function("stochastic_1e9_step", |b| b.iter(|| black_box(sim.step().expect("step"))));
    g.bench_function("stochastic_1e9_render_1280x720", |b| {
        b.iter(|| black_box(renderer.render(&sim).c0.sum()))
    });
    g.bench_function("stochastic_1e9_step_and_render", |b| {
        b.iter(|| {
            sim.step().expect("step");
            black_box(renderer.render(&sim).c0.sum())
        })
    });
    g.finish();

    let mut g = c.benchmark_group("step");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for method in [Method::Stochastic, Method::BruteForce] {
        let mut sim = SparkleSim::new(config(method, 1e7), 1).expect("valid");
        g.bench_with_input(BenchmarkId::new(format!("{method:?}"), "1e7"), &(), |b, _| {
            b.iter(|| black_box(sim.step().expect("step")))
        });
    }
    g.finish();
}

criterion_group!(benches, reference::reference, bench);
criterion_main!(benches);
