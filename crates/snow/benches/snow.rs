//! Snow hot paths (issue 5's speed targets): the snow probability of a scene (64
//! directions at 256×256) and one accumulation + stabilisation step of the paper's Fig 8
//! setting (five 128×128 maps, one per primitive).

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use phenomena_snow::mesh::{primitives_scene, table_scene};
use phenomena_snow::{SnowParams, SnowSim};
use std::hint::black_box;

fn probability(c: &mut Criterion) {
    let params =
        SnowParams { map_resolution: 128, directions: 64, shadow_resolution: 256, ..SnowParams::default() };
    let mut sim = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 1).expect("table scene");
    c.bench_function("snow_probability_table_64dirs_256", |b| {
        b.iter(|| sim.update_probability().expect("raster"))
    });
}

fn step(c: &mut Criterion) {
    // Fig 8: one group per object, 128×128 maps, repose 45°; 2 cm/h in 0.1 h steps,
    // measured from the state after 5 h (10 cm of snow).
    let params = SnowParams {
        map_resolution: 128,
        directions: 16,
        object_groups: Some(vec![0, 1, 2, 3, 4]),
        ..SnowParams::default()
    };
    let mut sim = SnowSim::new(primitives_scene(), params, 1).expect("primitives");
    assert_eq!(sim.maps().len(), 5);
    for _ in 0..50 {
        sim.step();
    }
    c.bench_function("snow_step_5_maps_128", |b| {
        b.iter_batched_ref(|| sim.clone(), |s| black_box(s.step()), BatchSize::LargeInput)
    });
}

criterion_group!(benches, probability, step);
criterion_main!(benches);
