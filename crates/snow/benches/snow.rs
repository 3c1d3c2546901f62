//! Snow hot paths (its speed targets): the snow probability of a scene (64
//! directions at 256×256) and one accumulation + stabilisation step of the paper's Fig 8
//! setting (five 128×128 maps, one per primitive).

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use phenomena_snow::mesh::{primitives_scene, table_scene, village_scene, yard_config, yard_scene};
use phenomena_snow::reference::naive_vertex_probability;
use phenomena_snow::{SnowConfig, SnowSim};
use std::hint::black_box;

/// The fixed reference workload reported beside these numbers.
#[path = "../../core/benches/shared/reference.rs"]
mod reference;

fn probability(c: &mut Criterion) {
    let params =
        SnowConfig { map_resolution: 128, directions: 64, shadow_resolution: 256, ..SnowConfig::default() };
    let mut sim = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 1).expect("table scene");
    c.bench_function("snow_probability_table_64dirs_256", |b| {
        b.iter(|| sim.update_probability().expect("raster"))
    });
}

/// Target: a ~13,000-triangle scene, 64 directions, 256×256 (maps and depth
/// maps) in ≤ 100 ms (stretch 40 ms).
fn village(c: &mut Criterion) {
    let mesh = village_scene();
    let params =
        SnowConfig { map_resolution: 256, directions: 64, shadow_resolution: 256, ..SnowConfig::default() };
    let mut sim = SnowSim::new(mesh.clone(), params, 1).expect("village");
    let mut group = c.benchmark_group("snow_village");
    group.sample_size(10);
    group.bench_function(format!("probability_{}_triangles_64dirs_256", mesh.len()), |b| {
        b.iter(|| sim.update_probability().expect("raster"))
    });
    // The paper's comparison (Table 1): per-vertex rays against every triangle, here with
    // 8 directions, against the shadow-map method with the same 8 directions.
    let params8 =
        SnowConfig { map_resolution: 256, directions: 8, shadow_resolution: 256, ..SnowConfig::default() };
    let mut sim8 = SnowSim::new(mesh.clone(), params8, 1).expect("village");
    let dirs: Vec<_> = sim8.directions().to_vec();
    group.bench_function("probability_8dirs_256", |b| b.iter(|| sim8.update_probability().expect("raster")));
    group.bench_function("naive_vertex_ray_casting_8dirs", |b| {
        b.iter(|| black_box(naive_vertex_probability(&mesh, &dirs)))
    });
    group.finish();
}

/// The snow's glitter (`glitter::glints`) on the village of `scenes/snow-village.toml`
/// after 3 h of snow, seen from its camera under the default sun: the upper faces of the
/// snow that face the eye and the sun (the renderer also drops faces out of the frame
/// or wholly in shadow).
fn glitter(c: &mut Criterion) {
    use phenomena_snow::glitter::{Viewing, glints};
    let params = SnowConfig {
        map_resolution: 200,
        directions: 64,
        rate_cm_per_h: 5.0,
        time_step_h: 0.1,
        repose_deg: 45.0,
        ..SnowConfig::default()
    };
    let mut sim = SnowSim::new(village_scene(), params, 1).expect("village");
    for _ in 0..30 {
        sim.step().expect("step");
    }
    let snow = phenomena_snow::export::snow_mesh(&sim);
    let eye = glam::Vec3::new(24.0, 14.0, 30.0);
    let sun = phenomena_snow::SnowRenderSettings::default().sun_direction.normalize();
    let faces: Vec<[glam::Vec3; 3]> = snow
        .indices
        .chunks_exact(3)
        .map(|t| [0, 1, 2].map(|k| snow.positions[t[k] as usize]))
        .filter(|t| {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            n.y > 0.0 && n.dot(eye - t[0]) > 0.0 && n.dot(sun) > 0.0
        })
        .collect();
    // The renderer's mesh of that snow, made every frame (`export::snow_surface`).
    c.bench_function("snow_surface_village_200", |b| {
        b.iter(|| black_box(phenomena_snow::export::snow_surface(&sim).triangles()))
    });
    let g = phenomena_snow::Glitter::default();
    let mut group = c.benchmark_group("snow_glitter");
    group.sample_size(20);
    group.bench_function(format!("village_{}_faces", faces.len()), |b| {
        b.iter(|| black_box(glints(&faces, Viewing { eye, sun }, &g, 1).len()))
    });
    group.finish();
}

fn step(c: &mut Criterion) {
    // Fig 8: one group per object, 128×128 maps, repose 45°; 2 cm/h in 0.1 h steps,
    // measured from the state after 5 h (10 cm of snow).
    let params = SnowConfig {
        map_resolution: 128,
        directions: 16,
        object_groups: Some(vec![0, 1, 2, 3, 4]),
        ..SnowConfig::default()
    };
    let mut sim = SnowSim::new(primitives_scene(), params, 1).expect("primitives");
    assert_eq!(sim.maps().len(), 5);
    for _ in 0..50 {
        sim.step().unwrap();
    }
    c.bench_function("snow_step_5_maps_128", |b| {
        b.iter_batched_ref(|| sim.clone(), |s| black_box(s.step().unwrap()), BatchSize::LargeInput)
    });
    // Step: accumulation + stabilisation + remesh (the snow solids).
    c.bench_function("snow_step_and_remesh_5_maps_128", |b| {
        b.iter_batched_ref(
            || sim.clone(),
            |s| {
                black_box(s.step().unwrap());
                black_box(phenomena_snow::export::snow_mesh(s))
            },
            BatchSize::LargeInput,
        )
    });
}

/// Workload: `scenes/snow-yard.toml` (256² maps, 64 directions, 4 cm/h in
/// 0.25 h steps, repose 35°): criterion's times for one step early in the snowfall, one
/// after 9 hours and the last of 12 hours, when the piles under the eaves are deep; then
/// [`yard_steps`], every step of the 12 hours.
fn yard(c: &mut Criterion) {
    let params = yard_config();
    let fresh = SnowSim::new(yard_scene(), params, 1).expect("yard");
    let mut sim = fresh.clone();
    let mut group = c.benchmark_group("snow_yard_256");
    group.sample_size(10);
    for (label, until) in [("step_at_0h25", 1), ("step_at_9h", 36), ("step_at_11h45", 47)] {
        while sim.steps() < until {
            sim.step().unwrap();
        }
        group.bench_function(label, |b| {
            b.iter_batched_ref(|| sim.clone(), |s| black_box(s.step().unwrap()), BatchSize::LargeInput)
        });
    }
    // The renderer's mesh of the yard's snow after the 12 hours (`export::snow_surface`).
    group.bench_function("surface_at_11h45", |b| {
        b.iter(|| black_box(phenomena_snow::export::snow_surface(&sim).triangles()))
    });
    group.finish();
    yard_steps(&fresh);
}

/// Target, checked over every step of the 12 hours (48 steps): each step within
/// 30 ms, and the last at most twice the median of the first ten. The 12 hours are run
/// five times from the same start and each step's time is its median over the runs (the
/// machine is shared: a median drops the runs another process slowed). Printed, not
/// asserted: timings are the machine's as much as the code's.
#[allow(clippy::print_stderr, reason = "the bench reports the per-step check beside criterion's times")]
fn yard_steps(fresh: &SnowSim) {
    const STEPS: usize = 48;
    const RUNS: usize = 5;
    let mut times: Vec<Vec<f64>> = (0..STEPS).map(|_| Vec::with_capacity(RUNS)).collect();
    for _ in 0..RUNS {
        let mut sim = fresh.clone();
        for t in &mut times {
            let start = std::time::Instant::now();
            black_box(sim.step().unwrap());
            t.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let per_step: Vec<f64> = times.iter_mut().map(median).collect();
    let first_ten = median(&mut per_step[..10].to_vec());
    let (worst, at) =
        per_step.iter().enumerate().fold((0.0, 0), |w, (i, &t)| if t > w.0 { (t, i) } else { w });
    let last = per_step[STEPS - 1];
    let met = worst <= 30.0 && last <= 2.0 * first_ten;
    eprintln!(
        "snow_yard_256/12h: median of the first ten steps {first_ten:.1} ms, last (step {}) {last:.1} ms ({:.2}x), slowest step {at} {worst:.1} ms; target (every step <= 30 ms, last <= 2x the first ten): {}",
        STEPS - 1,
        last / first_ten,
        if met { "met" } else { "NOT met" }
    );
    let row = |range: std::ops::Range<usize>| {
        per_step[range].iter().map(|t| format!("{t:.1}")).collect::<Vec<_>>().join(" ")
    };
    eprintln!("  steps 0-23, ms: {}", row(0..24));
    eprintln!("  steps 24-47, ms: {}", row(24..STEPS));
}

criterion_group!(benches, reference::reference, probability, village, glitter, step, yard);
criterion_main!(benches);
