//! The snow mesh's edges follow the objects' shapes, not the texel grid (issue 40: "stair
//! steps on the cone and sphere"), on the built-in primitives after 8 hours of snow.

use glam::{Vec2, Vec3};
use phenomena_snow::export::{TriMesh, snow_mesh};
use phenomena_snow::mesh::primitives_scene;
use phenomena_snow::{SnowConfig, SnowSim};

/// `scenes/snow-primitives.toml`'s snow, 80 steps of 0.1 h.
fn primitives_snow() -> (SnowSim, TriMesh) {
    let config = SnowConfig {
        map_resolution: 128,
        directions: 64,
        spread_deg: 8.0,
        rate_cm_per_h: 5.0,
        time_step_h: 0.1,
        repose_deg: 45.0,
        object_groups: Some(vec![0, 1, 2, 3, 4]),
        ..SnowConfig::default()
    };
    let mut sim = SnowSim::new(primitives_scene(), config, 1).unwrap();
    for _ in 0..80 {
        sim.step().unwrap();
    }
    let mesh = snow_mesh(&sim);
    (sim, mesh)
}

/// The triangles of `mesh` with their unit normal, area and centroid.
fn faces(mesh: &TriMesh) -> impl Iterator<Item = (Vec3, f32, Vec3)> + '_ {
    mesh.indices.chunks_exact(3).map(|t| {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        let cross = (b - a).cross(c - a);
        (cross.normalize_or_zero(), 0.5 * cross.length(), (a + b + c) / 3.0)
    })
}

#[test]
#[allow(clippy::print_stdout)]
fn the_cylinders_rim_is_round_and_the_spheres_sides_hold_no_blocks() {
    let (sim, mesh) = primitives_snow();
    let texel = sim.footprint().texel_m;

    // The cylinder (radius 0.5 m, top at 0.9 m, axis at x = z = 1.3): the snow on its top
    // ends in a side at its rim. A side that follows the texel grid faces ±x or ±z, on
    // average 22.5° off the rim's outward normal for a circle; a side along the circle
    // is off by at most half the angle a texel-long chord spans, t / 2r = 2.8°.
    let axis = Vec2::new(1.3, 1.3);
    let (mut off, mut area) = (0.0f32, 0.0f32);
    for (n, a, c) in faces(&mesh) {
        let radial = Vec2::new(c.x, c.z) - axis;
        if n.y.abs() > 0.1 || c.y < 0.85 || radial.length() > 0.5 + 2.0 * texel {
            continue;
        }
        let outward = radial.normalize();
        off += a * Vec2::new(n.x, n.z).normalize().dot(outward).clamp(-1.0, 1.0).acos().to_degrees();
        area += a;
    }
    assert!(area > 0.0, "no side at the cylinder's rim");
    let mean_off = off / area;
    println!("cylinder rim: sides {area:.4} m², {mean_off:.2}° off the outward normal on average");
    // Between the two: a side along the circle, smoothed within half a texel.
    assert!(mean_off < 8.0, "the rim's sides are {mean_off:.1}° off the outward normal: stair steps");

    // The sphere (radius 0.7 m, centre (1.3, 0.7, -1.3)): no snow stands on its sides
    // steeper than the repose (45°) in texel-sized blocks; its walls (near-vertical
    // faces) lie only on the cap above 45° of latitude, or in the drift at its foot.
    let centre = Vec3::new(1.3, 0.7, -1.3);
    let blocks: f32 = faces(&mesh)
        .filter(|&(n, _, c)| {
            let from = c - centre;
            n.y.abs() < 0.1 && from.length() < 0.7 + 2.0 * texel && from.y > 0.05 && from.y < 0.7 * 0.7
        })
        .map(|(_, a, _)| a)
        .sum();
    println!("sphere: {blocks:.5} m² of snow sides on its steep band");
    assert!(blocks < 1e-6, "{blocks} m² of snow sides on the sphere's steep band (blocks of snow)");
}
