//! Snow hot paths (issue 5): the snow probability of a scene and one accumulation +
//! stabilisation step.

use criterion::{Criterion, criterion_group, criterion_main};
use phenomena_snow::mesh::table_scene;
use phenomena_snow::{SnowParams, SnowSim};
use std::hint::black_box;

fn table(c: &mut Criterion) {
    let params =
        SnowParams { map_resolution: 128, directions: 64, shadow_resolution: 256, ..SnowParams::default() };
    let mut sim = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 1).expect("table scene");
    c.bench_function("snow_probability_table_64dirs_256", |b| {
        b.iter(|| sim.update_probability().expect("raster"))
    });
    c.bench_function("snow_step_table_128", |b| b.iter(|| black_box(sim.step())));
}

criterion_group!(benches, table);
criterion_main!(benches);
