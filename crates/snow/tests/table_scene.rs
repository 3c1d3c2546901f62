//! Evidence on the table scene of the paper's Fig 7: the probability under the
//! table, its edges with and without spread, the angle of repose, conservation, snow
//! falling off the table onto the ground, and thread-count independence.

use phenomena_snow::mesh::table_scene;
use phenomena_snow::{SnowConfig, SnowSim};

/// A 4 m ground with a 1.2 m table 0.7 m high in the middle.
fn sim(spread_deg: f32, directions: u32, repose_deg: f32) -> SnowSim {
    let params = SnowConfig {
        map_resolution: 80,
        directions,
        spread_deg,
        shadow_resolution: 256,
        repose_deg,
        ..SnowConfig::default()
    };
    SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 3).expect("table scene")
}

/// The map holding the ground (the one with the most snow-possible texels).
fn ground_map(s: &SnowSim) -> usize {
    let area = |m: &phenomena_snow::SnowMap| (0..m.ground_m.len()).filter(|&k| m.possible(k)).count();
    (0..s.maps().len()).max_by_key(|&i| area(&s.maps()[i])).expect("maps")
}

/// Probability along the row through the table's centre, on the ground map, from x = -2
/// to 2 (texel centres).
fn ground_row(s: &SnowSim) -> Vec<(f32, f32)> {
    let fp = s.footprint();
    let g = &s.maps()[ground_map(s)];
    let j = fp.n / 2;
    (0..fp.n)
        .filter(|&i| g.possible(j * fp.n + i))
        .map(|i| (fp.centre(i, j).x, g.probability[j * fp.n + i]))
        .collect()
}

#[test]
fn the_ground_under_the_table_gets_little_snow() {
    let s = sim(10.0, 64, 45.0);
    let row = ground_row(&s);
    let at = |x: f32| row.iter().min_by(|a, b| (a.0 - x).abs().total_cmp(&(b.0 - x).abs())).unwrap().1;
    // Open ground, 1.5 m from the centre (0.9 m outside the table's edge at 0.6 m; at a
    // 10° spread a 0.7 m high edge shades at most 0.7·tan(3σ) = 0.39 m): fully exposed.
    assert!(at(-1.7) > 0.99 && at(1.7) > 0.99, "open ground: {} {}", at(-1.7), at(1.7));
    // Under the middle of the table: hidden from every direction within 3σ (the table
    // edge is 0.6 m away at 0.65 m below the top: 42° off vertical, over 4σ).
    assert!(at(0.0) < 0.01, "under the table: {}", at(0.0));
    // The table top is exposed.
    let fp = s.footprint();
    let c = (fp.n / 2) * fp.n + fp.n / 2;
    let g = ground_map(&s);
    let top =
        s.maps().iter().enumerate().find(|(i, m)| *i != g && m.possible(c)).expect("the table top's map").1;
    assert!(top.possible(c) && top.probability[c] > 0.99);
}

#[test]
fn spread_softens_the_shadow_edge_and_zero_spread_makes_it_sharp() {
    // Across the table's edge at x = 0.6 m, on the ground (0.7 m below the top's edge).
    let transition =
        |s: &SnowSim| ground_row(s).iter().filter(|(x, p)| *x > 0.0 && *p > 0.02 && *p < 0.98).count();
    let sharp = sim(0.0, 16, 45.0);
    let soft = sim(10.0, 64, 45.0);
    // Zero spread, straight down: the shadow is the table top's outline; texels go from
    // 0 to 1 within one texel (only a texel cut by the edge may be in between).
    assert!(transition(&sharp) <= 1, "zero spread: {} texels in transition", transition(&sharp));
    // With a 10° spread the penumbra is 2·0.7·tan(10°) ≈ 0.25 m wide on each side of
    // the edge at 1σ: several 5 cm texels.
    assert!(transition(&soft) >= 4, "10° spread: {} texels in transition", transition(&soft));
    // And P rises monotonically (up to sampling noise of 64 directions) from under the
    // table outwards.
    let row: Vec<f32> = ground_row(&soft).iter().filter(|(x, _)| *x > 0.0).map(|r| r.1).collect();
    for w in row.windows(2) {
        assert!(w[1] >= w[0] - 2.0 / 64.0, "{row:?}");
    }
}

#[test]
fn snow_rests_at_the_angle_of_repose_and_none_is_lost() {
    let mut s = sim(10.0, 16, 30.0);
    let add_per_step = |s: &SnowSim| {
        let fp = s.footprint();
        let t2 = f64::from(fp.texel_m).powi(2);
        let m = f64::from(s.config().rate_cm_per_h) * 0.01 * f64::from(s.config().time_step_h);
        s.maps().iter().map(|map| map.probability.iter().map(|&p| f64::from(p)).sum::<f64>()).sum::<f64>()
            * t2
            * m
    };
    let mut added = 0.0;
    // Heavy snow: 10 cm/h for 6 h in 0.1 h steps, 60 cm in all: more than the table's
    // 0.6 m half-width times tan(30°) = 35 cm, so the pile reaches the repose.
    let mut params = s.config().clone();
    params.rate_cm_per_h = 10.0;
    s = SnowSim::new(s.mesh().clone(), params, 3).unwrap();
    for _ in 0..60 {
        added += add_per_step(&s);
        let stats = s.step().unwrap();
        assert!(stats.stable, "stabilisation did not finish in {} passes", stats.passes);
        // No snow-covered texel is steeper than the repose towards any neighbour.
        let excess = s.max_slope_excess();
        assert!(excess <= 1e-4, "slope exceeds tan(30°) by {excess}");
        // On the maps plus off the scene: all that fell (f32 depths: 1e-5 relative).
        let total = stats.volume_m3 + stats.fallen_off_m3;
        assert!((total - added).abs() <= 1e-5 * added, "volume {total} vs added {added}");
    }
}

#[test]
fn snow_sliding_off_the_table_lands_on_the_ground_beside_it() {
    // Straight down (no snow under the table), a low angle of repose and a lot of snow:
    // the table top sheds snow over its edges onto the ground map next to it, so the
    // ground just outside the edge holds more than the open ground far away.
    let params = SnowConfig {
        map_resolution: 80,
        directions: 4,
        spread_deg: 0.0,
        repose_deg: 20.0,
        rate_cm_per_h: 100.0,
        ..SnowConfig::default()
    };
    let mut s = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 3).unwrap();
    for _ in 0..10 {
        s.step().unwrap();
    }
    let fp = s.footprint();
    let g = &s.maps()[ground_map(&s)];
    let j = fp.n / 2;
    let at = |x: f32| {
        let i = ((x - fp.origin.x) / fp.texel_m) as usize;
        g.snow_m[j * fp.n + i]
    };
    // The table's edge is at x = 0.6 m: just outside it versus 1.7 m out.
    let (beside, far) = (at(0.65), at(1.7));
    assert!(beside > far * 1.2, "beside the table {beside} m, open ground {far} m");
    assert!(s.fallen_off_m3() >= 0.0);
}

#[test]
fn any_thread_count_gives_the_same_snow() {
    // Either stabiliser (both sequential; the probability is computed in shares).
    for stabiliser in [phenomena_snow::Stabiliser::Flood, phenomena_snow::Stabiliser::Relaxation] {
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| {
                let table = sim(10.0, 16, 35.0);
                let params = SnowConfig { stabiliser, ..table.config().clone() };
                let mut s = SnowSim::new(table.mesh().clone(), params, 3).unwrap();
                for _ in 0..5 {
                    s.step().unwrap();
                }
                // Bits, not values: the ground is NaN where a map holds no snow.
                s.maps()
                    .iter()
                    .flat_map(|m| {
                        m.ground_m.iter().chain(&m.snow_m).chain(&m.probability).map(|v| v.to_bits())
                    })
                    .collect::<Vec<u32>>()
            })
        };
        let one = run(1);
        assert!(one == run(2), "{stabiliser:?}: 1 vs 2 threads");
        assert!(one == run(3), "{stabiliser:?}: 1 vs 3 threads");
        // 16 directions over 7 threads make 6 shares of 3; and the same simulation moved
        // from an 8-thread pool to that one keeps no counts from its earlier workers.
        assert!(one == run(7), "{stabiliser:?}: 1 vs 7 threads");
    }
    let pool = |threads: usize| rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let mut s = sim(10.0, 16, 35.0);
    let reference = s.maps().iter().map(|m| m.probability.clone()).collect::<Vec<_>>();
    pool(8).install(|| s.update_probability().unwrap());
    pool(7).install(|| s.update_probability().unwrap());
    assert!(s.maps().iter().zip(&reference).all(|(m, r)| &m.probability == r), "8 then 7 threads");
}

#[test]
fn lying_snow_shades_like_any_occluder() {
    // Snow moving towards +x at 30° from the vertical, no spread. Ground texels at
    // x in (1.0, 1.29) m are just out of the bare table's shadow (the ray up from x
    // passes the top's edge x = 0.6 at height (x - 0.6)/tan 30° > 0.7 m), but inside the
    // shadow of 0.5 m of snow lying on the top (that height is below 1.2 m).
    let params = SnowConfig {
        map_resolution: 100,
        directions: 4,
        spread_deg: 0.0,
        main_tilt_deg: [30.0, 0.0],
        ..SnowConfig::default()
    };
    let mut s = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 3).unwrap();
    let fp = s.footprint();
    let g = ground_map(&s);
    let j = fp.n / 2;
    let band: Vec<usize> =
        (0..fp.n).filter(|&i| (1.05..1.25).contains(&fp.centre(i, j).x)).map(|i| j * fp.n + i).collect();
    assert!(band.len() >= 3);
    assert!(band.iter().all(|&k| s.maps()[g].probability[k] == 1.0), "lit before");
    let top = (0..s.maps().len()).find(|&m| m != g && s.maps()[m].possible(j * fp.n + fp.n / 2)).unwrap();
    for k in 0..fp.n * fp.n {
        if s.maps()[top].possible(k) {
            s.maps_mut()[top].snow_m[k] = 0.5;
        }
    }
    s.update_probability().unwrap();
    assert!(band.iter().all(|&k| s.maps()[g].probability[k] == 0.0), "shaded by the snow on the table");
}

#[test]
fn changed_grounds_are_found_again() {
    // The probability keeps the list of snow-possible texels between calls; a ground
    // changed through `maps_mut` must be taken into account.
    let mut s = sim(5.0, 8, 35.0);
    let g = ground_map(&s);
    let top = (0..s.maps().len()).find(|&m| m != g).expect("the table top's map");
    let n = s.footprint().n;
    let on = (0..n * n).find(|&k| s.maps()[top].possible(k)).unwrap();
    let off = (0..n * n).find(|&k| !s.maps()[top].possible(k)).unwrap();
    assert!(s.maps()[top].probability[on] > 0.0 && s.maps()[top].probability[off] == 0.0);
    // Remove a texel of the top and add one 5 m above the scene (open to every direction).
    s.maps_mut()[top].ground_m[on] = f32::NAN;
    s.maps_mut()[top].ground_m[off] = 5.0;
    s.update_probability().unwrap();
    assert_eq!(s.maps()[top].probability[on], 0.0);
    assert_eq!(s.maps()[top].probability[off], 1.0);
}

/// A surface split between two maps (here a ground square whose two triangles are given
/// different groups, as the automatic grouping does to a ground under objects) holds snow
/// as one surface: no trench along the join, nothing lost there. Before the fix a
/// texel next to a slightly higher neighbour on the other map measured its slope to its
/// own ground, so snow deeper than the repose rise fell off the scene along the diagonal.
#[test]
fn a_surface_split_between_two_maps_holds_snow_evenly_across_the_join() {
    use glam::Vec3;
    use phenomena_snow::mesh::{Mesh, ground_square};
    let mut mesh = Mesh::default();
    let [a, b] = ground_square(2.0);
    mesh.push_object(&[a], 0);
    mesh.push_object(&[b], 1);
    // A 20 cm box in one corner, so the two halves are not exactly alike.
    mesh.push_object(&phenomena_snow::mesh::cuboid(Vec3::new(1.2, 0.0, -1.8), Vec3::new(1.6, 0.2, -1.4)), 2);
    let params = SnowConfig {
        map_resolution: 64,
        directions: 16,
        spread_deg: 0.0,
        repose_deg: 35.0,
        rate_cm_per_h: 10.0,
        time_step_h: 0.5,
        object_groups: Some(vec![0, 1, 2]),
        ..SnowConfig::default()
    };
    let mut s = SnowSim::new(mesh, params, 1).expect("split ground");
    assert!(s.maps().len() >= 2);
    // 20 cm of snow, over three times the repose rise of a 6.6 cm texel (4.6 cm).
    for _ in 0..4 {
        assert!(s.step().unwrap().stable);
    }
    let fp = s.footprint();
    let rise = 35f32.to_radians().tan() * fp.texel_m;
    assert!(0.2 > 3.0 * rise);
    // Along the diagonal (the join), away from the ground's edge and the box: the snow is
    // as deep as anywhere on open ground (the probability is 1 there: no occluder, no
    // spread), to f32 rounding.
    let n = fp.n;
    let mut checked = 0;
    for d in 10..n - 10 {
        for (i, j) in [(d, d), (d + 1, d), (d, d + 1)] {
            let p = fp.centre(i, j);
            if p.x > 0.8 && p.y < -0.8 {
                continue; // near the box
            }
            let k = j * n + i;
            let depth: f32 = s.maps().iter().filter(|m| m.possible(k)).map(|m| m.snow_m[k]).sum();
            assert!((depth - 0.2).abs() < 1e-5, "texel ({i}, {j}) at the join holds {depth} m, not 0.2 m");
            checked += 1;
        }
    }
    assert!(checked > 100);
    // What fell off went over the ground's outer edge only: at most the repose wedges
    // along the 16 m perimeter (½ · 0.2 m · 0.2 m / tan 35° per metre).
    let wedges = 16.0 * 0.5 * 0.2 * 0.2 / 35f64.to_radians().tan();
    assert!(s.fallen_off_m3() < wedges, "{} m³ fell off (wedges: {wedges} m³)", s.fallen_off_m3());
}

/// The relaxation visits only texels next to a change: on the yard (a
/// steep roof draining onto piles, trees, a fence, a ground split between two maps), it
/// gives bit for bit the snow, the fallen volume and the passes of the sweep that visits
/// every texel in every pass. 100² maps: not a whole number of 64-texel words, so the
/// sets' last word is partly outside the map.
#[test]
fn the_sparse_stabilisation_equals_visiting_every_texel() {
    let params = SnowConfig {
        map_resolution: 100,
        directions: 16,
        stabiliser: phenomena_snow::Stabiliser::Relaxation,
        ..phenomena_snow::mesh::yard_config()
    };
    let mut sparse = SnowSim::new(phenomena_snow::mesh::yard_scene(), params, 1).expect("yard");
    let mut dense = sparse.clone();
    dense.set_dense_sweeps(true);
    for step in 0..24 {
        let (a, b) = (sparse.step().unwrap(), dense.step().unwrap());
        assert_eq!(a.passes, b.passes, "step {step}");
        assert!(a.stable && b.stable, "step {step}");
        assert_eq!(a.fallen_off_m3.to_bits(), b.fallen_off_m3.to_bits(), "step {step}");
        for (ma, mb) in sparse.maps().iter().zip(dense.maps()) {
            assert!(ma.snow_m.iter().zip(&mb.snow_m).all(|(x, y)| x.to_bits() == y.to_bits()), "step {step}");
        }
    }
    // Something moved: the roof drained onto the ground.
    assert!(sparse.fallen_off_m3() > 0.0 && dense.steps() == 24);
}

/// The same across a join of two maps (its split ground), where a texel's slope
/// past its region's edge is measured to the other map's surface: pits dug on one side
/// next to the join avalanche across it. (The sparse sweep also marks the other map's
/// texels next to any change for this; neither this case nor the yard has been seen to
/// need it, so it is kept as the safe choice, not as a tested one.)
#[test]
fn the_sparse_stabilisation_equals_visiting_every_texel_across_a_join() {
    use phenomena_snow::mesh::{Mesh, ground_square};
    let mut mesh = Mesh::default();
    let [a, b] = ground_square(2.0);
    mesh.push_object(&[a], 0);
    mesh.push_object(&[b], 1);
    let params = SnowConfig {
        map_resolution: 50,
        directions: 4,
        spread_deg: 0.0,
        repose_deg: 35.0,
        rate_cm_per_h: 10.0,
        time_step_h: 0.5,
        object_groups: Some(vec![0, 1]),
        stabiliser: phenomena_snow::Stabiliser::Relaxation,
        ..SnowConfig::default()
    };
    let mut sparse = SnowSim::new(mesh, params, 1).expect("split ground");
    assert_eq!(sparse.maps().len(), 2);
    for _ in 0..3 {
        sparse.step().unwrap();
    }
    let n = sparse.footprint().n;
    // Pits on map 1 around texels next to map 0's region: each such texel k of map 1
    // keeps its snow while its other neighbours on map 1 lose theirs, so k avalanches
    // into the pit and map 0's texel across the join, level with k before and not
    // given any snow, becomes steep towards it.
    let (m0, m1) = (sparse.maps()[0].clone(), sparse.maps()[1].clone());
    let mut pits = 0;
    for j in 2..n - 2 {
        for i in 2..n - 2 {
            let k = j * n + i;
            let across = [k - 1, k + 1, k - n, k + n].into_iter().filter(|&q| m0.possible(q)).count();
            if !m1.possible(k) || across == 0 || (i + j) % 4 != 0 {
                continue;
            }
            for q in [k - 1, k + 1, k - n, k + n] {
                if m1.possible(q) {
                    sparse.maps_mut()[1].snow_m[q] = 0.0;
                }
            }
            pits += 1;
        }
    }
    assert!(pits > 5);
    let mut dense = sparse.clone();
    dense.set_dense_sweeps(true);
    for step in 0..3 {
        let (a, b) = (sparse.step().unwrap(), dense.step().unwrap());
        assert_eq!(a.passes, b.passes, "step {step}");
        assert_eq!(a.fallen_off_m3.to_bits(), b.fallen_off_m3.to_bits(), "step {step}");
        for (ma, mb) in sparse.maps().iter().zip(dense.maps()) {
            assert!(ma.snow_m.iter().zip(&mb.snow_m).all(|(x, y)| x.to_bits() == y.to_bits()), "step {step}");
        }
    }
}

/// Snow walled in by a higher snow surface stays (§2.4.2: the snow falls to the highest
/// map whose snow-possible region, its ground, lies below the source). A low block in
/// deep snow: the ground's snow stands above the block's, so past the block's edge the
/// slope is measured up to the ground's snow surface and nothing moves. Before the fix for split maps,
/// fix the lower map was chosen by its snow surface, none was found, and the block's snow
/// fell off the scene from the middle of the ground (found under the yard's bench).
#[test]
fn snow_walled_in_by_deeper_snow_stays_where_it_is() {
    use glam::Vec3;
    use phenomena_snow::mesh::{Mesh, cuboid, ground_square};
    let mut mesh = Mesh::default();
    mesh.push_object(&ground_square(2.0), 0);
    mesh.push_object(&cuboid(Vec3::new(-0.3, 0.0, -0.3), Vec3::new(0.3, 0.2, 0.3)), 1);
    let params = SnowConfig {
        map_resolution: 40,
        directions: 4,
        spread_deg: 0.0,
        repose_deg: 35.0,
        rate_cm_per_h: 0.0,
        object_groups: Some(vec![0, 1]),
        ..SnowConfig::default()
    };
    let mut s = SnowSim::new(mesh, params, 1).expect("a block on the ground");
    assert_eq!(s.maps().len(), 2);
    let top = (0..2).find(|&m| s.maps()[m].ground_m.iter().any(|&g| g > 0.1)).expect("the block's map");
    let ground = 1 - top;
    // 0.5 m on the ground, 0.1 m on the block (surface 0.3 m, under the ground's 0.5 m):
    // each flat, so within the repose everywhere but at the ground's outer edge.
    for (m, depth) in [(ground, 0.5), (top, 0.1)] {
        for d in s.maps_mut()[m].snow_m.iter_mut() {
            *d = depth;
        }
    }
    let block: Vec<f32> = s.maps()[top].snow_m.clone();
    assert!(s.step().unwrap().stable);
    let fp = s.footprint();
    let n = fp.n;
    for k in (0..n * n).filter(|&k| s.maps()[top].possible(k)) {
        assert_eq!(s.maps()[top].snow_m[k], block[k], "block texel {k} moved");
    }
    // The ground next to the block keeps its snow too (what left went over the outer edge).
    for k in (0..n * n).filter(|&k| s.maps()[ground].possible(k)) {
        let p = fp.centre(k % n, k / n);
        if p.abs().max_element() < 0.6 {
            assert_eq!(s.maps()[ground].snow_m[k], 0.5, "ground texel {k} near the block moved");
        }
    }
}

#[test]
fn a_spare_synced_from_a_simulation_steps_as_it_does() {
    // Heavy snow that slides off the table's edges and falls off the scene, with the
    // probability drawn again every second step: every part of the state a step reads.
    let params = SnowConfig {
        map_resolution: 48,
        directions: 8,
        shadow_resolution: 64,
        rate_cm_per_h: 400.0,
        repose_deg: 35.0,
        probability_every_steps: 2,
        ..SnowConfig::default()
    };
    let mut s = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 3).expect("table scene");
    let mut spare = s.clone();
    // The spare's own buffers (the flood's, the regions, the depth maps) are made and
    // used before it is synced, as a spare's are when it is synced frame after frame.
    for _ in 0..2 {
        spare.step().expect("steps");
    }
    for _ in 0..5 {
        s.step().expect("steps");
    }
    // The spare is three steps behind; synced, it takes the next steps as `s` does.
    spare.sync_from(&s);
    assert_eq!(spare.state(), s.state());
    for step in 0..4 {
        let (a, b) = (s.step().expect("steps"), spare.step().expect("steps"));
        assert_eq!(a, b, "step {step}");
        assert_eq!(spare.state(), s.state(), "step {step}");
        let bits = |sim: &SnowSim| -> Vec<u32> {
            sim.maps().iter().flat_map(|m| m.ground_m.iter().chain(&m.snow_m).map(|x| x.to_bits())).collect()
        };
        assert_eq!(bits(&spare), bits(&s), "step {step}");
    }
    assert!(s.fallen_off_m3() > 0.0, "the test should see snow fall off the scene");
}
