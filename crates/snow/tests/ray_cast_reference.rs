//! The shadow-map snow probability against the BVH ray-cast reference with the same
//! directions (mean |ΔP| ≤ 0.01 and 99th percentile ≤ 0.10 off silhouettes).

use phenomena_snow::mesh::{primitives_scene, table_scene, village_scene};
use phenomena_snow::reference::ray_cast_probability;
use phenomena_snow::{SnowConfig, SnowSim};

/// |ΔP| per texel off silhouettes, and how many texels were left out.
fn differences(sim: &SnowSim) -> (Vec<f32>, usize) {
    let reference = ray_cast_probability(sim);
    let edges = sim.silhouette_directions().unwrap();
    let n = sim.footprint().n;
    let mut out = Vec::new();
    let mut skipped = 0;
    for (m, (map, p_ref)) in sim.maps().iter().zip(&reference).enumerate() {
        for k in 0..n * n {
            if !map.possible(k) {
                continue;
            }
            // Silhouette rule (a): within 2 texels of the map's region edge (the texel's
            // area straddles geometry the shadow map resolves at its own pixel size).
            let (i, j) = ((k % n) as i64, (k / n) as i64);
            let near_edge = (-2..=2).any(|dj| {
                (-2..=2).any(|di| {
                    let (x, y) = (i + di, j + dj);
                    x < 0
                        || y < 0
                        || x >= n as i64
                        || y >= n as i64
                        || !map.possible((y * n as i64 + x) as usize)
                })
            });
            // Rule (b): the texel's depth-map sample is next to a silhouette in 10 % of the
            // directions or more (`SnowSim::silhouette_directions`). In such a direction
            // the two methods may disagree by one direction's share of P (1/32 here);
            // below 10 % of the directions that stays under the 0.10 tolerance.
            if near_edge || f32::from(edges[m][k]) >= 0.1 * sim.directions().len() as f32 {
                skipped += 1;
                continue;
            }
            out.push((map.probability[k] - p_ref[k]).abs());
        }
    }
    (out, skipped)
}

fn check(name: &str, sim: &SnowSim, min_kept: f64) {
    let (mut d, skipped) = differences(sim);
    d.sort_by(f32::total_cmp);
    let mean = d.iter().map(|&v| f64::from(v)).sum::<f64>() / d.len() as f64;
    let p99 = d[(d.len() as f64 * 0.99) as usize];
    // The rules must leave most of the maps in the comparison (measured: table 84 % of
    // 10,016 texels, mean 0.0010, p99 0.031; primitives 81 % of 17,408, mean 0.0062,
    // p99 0.063).
    let kept = d.len() as f64 / (d.len() + skipped) as f64;
    assert!(kept >= min_kept, "{name}: only {kept} of the texels compared");
    assert!(mean <= 0.01, "{name}: mean |ΔP| {mean}");
    assert!(p99 <= 0.10, "{name}: 99th percentile |ΔP| {p99}");
}

#[test]
fn the_table_scene_matches_ray_casting() {
    let params =
        SnowConfig { map_resolution: 100, directions: 32, spread_deg: 10.0, ..SnowConfig::default() };
    check("table", &SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 5).unwrap(), 0.75);
}

#[test]
fn the_primitives_scene_matches_ray_casting() {
    let params = SnowConfig {
        map_resolution: 128,
        directions: 32,
        spread_deg: 15.0,
        object_groups: Some(vec![0, 1, 2, 3, 4]),
        ..SnowConfig::default()
    };
    check("primitives", &SnowSim::new(primitives_scene(), params, 5).unwrap(), 0.75);
}

/// The village: 13,000 triangles of closed solids, whose back faces the depth maps skip
/// (`Cull::BackAmongFirst`), and the ground. Its benches, trunks and eaves are 0.05-0.3 m
/// across, so the depth maps need pixels of that order: at 1024² (0.06 m) measured mean
/// |ΔP| 0.0023, p99 0.031 on 74 % of the texels (the many small objects put more texels
/// within 2 of a region edge, rule (a), hence the lower floor on the share compared); at
/// 256² (0.23 m pixels, a 0.46 m bias) the same comparison gives mean 0.016 and p99 0.38.
#[test]
fn the_village_matches_ray_casting() {
    let params = SnowConfig {
        map_resolution: 256,
        directions: 32,
        shadow_resolution: 1024,
        spread_deg: 10.0,
        ..SnowConfig::default()
    };
    check("village", &SnowSim::new(village_scene(), params, 5).unwrap(), 0.70);
}
