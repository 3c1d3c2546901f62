//! Aurora hot paths (filled in as part 1 lands): see issue 3's speed targets.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec2;
use phenomena_aurora::field::{Grid, Poisson, solve_potential};
use std::hint::black_box;

fn poisson(c: &mut Criterion) {
    let grid = Grid { nx: 256, nz: 256, origin_km: Vec2::ZERO, cell_km: 1.5625 };
    let source: Vec<f64> = (0..grid.len()).map(|k| ((k * 7919) % 13) as f64).collect();
    c.bench_function("poisson_direct_256", |b| {
        b.iter(|| solve_potential(&grid, black_box(&source), Poisson::Direct))
    });
}

criterion_group!(benches, poisson);
criterion_main!(benches);
