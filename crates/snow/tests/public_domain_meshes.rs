//! Snow on real scanned and modelled meshes: the Stanford bunny and the Utah teapot
//! (public domain, converted once into `tests/data/` by `tools/mesh-convert`), each
//! standing on a ground square. Overhangs (the bunny's ears and chin, the teapot's spout
//! and handle) make several polygon groups; snow must rest at the angle of repose and
//! none may be lost.

use glam::Vec3;
use phenomena_snow::mesh::{Mesh, ground_square};
use phenomena_snow::{SnowConfig, SnowSim, load};

/// The mesh scaled to `height_m`, standing on y = 0 centred over the origin, on a
/// ground square of half-size `ground_half_m` (object 1).
fn on_ground(bytes: &[u8], height_m: f32, ground_half_m: f32) -> Mesh {
    let first = load::obj(bytes, 1.0).expect("test mesh loads").mesh;
    let (lo, hi) = first.bounds().expect("non-empty");
    let scale = height_m / (hi.y - lo.y);
    let mut mesh = load::obj(bytes, scale).expect("test mesh loads").mesh;
    let (lo, hi) = mesh.bounds().expect("non-empty");
    let shift = Vec3::new(-0.5 * (lo.x + hi.x), -lo.y, -0.5 * (lo.z + hi.z));
    for t in &mut mesh.triangles {
        for p in t.iter_mut() {
            *p += shift;
        }
    }
    mesh.push_object(&ground_square(ground_half_m), 1);
    mesh
}

fn check(name: &str, mesh: Mesh) {
    let params = SnowConfig {
        map_resolution: 96,
        directions: 16,
        spread_deg: 10.0,
        rate_cm_per_h: 10.0,
        repose_deg: 40.0,
        ..SnowConfig::default()
    };
    let mut s = SnowSim::new(mesh, params, 5).expect("snow sim");
    assert!(s.maps().len() >= 2, "{name}: overhangs need more than one polygon group");
    let fp = s.footprint();
    let t2 = f64::from(fp.texel_m).powi(2);
    let mut added = 0.0;
    for _ in 0..30 {
        let m = f64::from(s.config().rate_cm_per_h) * 0.01 * f64::from(s.config().time_step_h);
        added += s
            .maps()
            .iter()
            .map(|map| map.probability.iter().map(|&p| f64::from(p)).sum::<f64>())
            .sum::<f64>()
            * t2
            * m;
        let stats = s.step().unwrap();
        assert!(stats.stable, "{name}: stabilisation did not finish in {} passes", stats.passes);
        let excess = s.max_slope_excess();
        assert!(excess <= 1e-4, "{name}: slope exceeds tan(40°) by {excess}");
        // On the maps plus off the scene: all that fell (f32 depths: 1e-5 relative).
        let total = stats.volume_m3 + stats.fallen_off_m3;
        assert!((total - added).abs() <= 1e-5 * added, "{name}: volume {total} vs added {added}");
    }
    // Snow lies on the object itself, not only on the ground: some texel of a map other
    // than the ground's holds snow.
    let ground = (0..s.maps().len())
        .max_by_key(|&i| (0..s.maps()[i].ground_m.len()).filter(|&k| s.maps()[i].possible(k)).count())
        .expect("maps");
    let on_object =
        s.maps().iter().enumerate().filter(|(i, _)| *i != ground).any(|(_, m)| {
            (0..m.ground_m.len()).any(|k| m.possible(k) && m.surface(k) > m.ground_m[k] + 0.005)
        });
    assert!(on_object, "{name}: no snow on the object");
}

#[test]
fn snow_on_the_stanford_bunny() {
    check("bunny", on_ground(include_bytes!("../../../tests/data/bunny.obj"), 0.6, 1.0));
}

#[test]
fn snow_on_the_utah_teapot() {
    check("teapot", on_ground(include_bytes!("../../../tests/data/teapot.obj"), 0.5, 1.0));
}
