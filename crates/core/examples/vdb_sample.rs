//! Writes test volumes with `phenomena_core::vdb` and, beside each, what OpenVDB should
//! read from it, for `tools/vdb-check/check.py` (run by `tools/vdb-check/run.sh`).
//!
//! `cargo run --release -p phenomena-core --example vdb_sample -- OUT_DIR`
//!
//! For every `NAME.vdb` it writes `NAME.json`: per grid the name, value type, class,
//! active voxel count, min and max (lexicographic for vectors, as OpenVDB's
//! `evalMinMax`), bounding box, voxel size, the world position of one index, probe
//! voxels, metadata, and optionally a binary dump of every active voxel (`i32` x, y, z
//! then the value's `f32` components, little-endian) to compare voxel by voxel.

#![allow(clippy::print_stdout, reason = "a command-line tool: it reports what it wrote")]

use phenomena_core::rng::{Purpose, Stream};
use phenomena_core::vdb::{AnyGrid, Grid, GridClass, Metadata, Transform, Voxel, encode};
use serde_json::{Value, json};
use std::path::Path;

/// What a grid's expectations need from a value type.
trait Sample: Voxel {
    const TYPE: &'static str;
    fn parts(self) -> Vec<f32>;
    fn json(self) -> Value {
        let c = self.parts();
        if c.len() == 1 { json!(c[0]) } else { json!(c) }
    }
}

impl Sample for f32 {
    const TYPE: &'static str = "float";
    fn parts(self) -> Vec<f32> {
        vec![self]
    }
}

impl Sample for [f32; 3] {
    const TYPE: &'static str = "vec3s";
    fn parts(self) -> Vec<f32> {
        self.to_vec()
    }
}

/// Every active voxel, sorted by coordinate.
fn active<T: Sample>(grid: &Grid<T>) -> Vec<([i32; 3], T)> {
    let mut out = Vec::new();
    for (origin, values) in grid.leaves() {
        for (n, v) in values.iter().enumerate() {
            if !v.is_zero() {
                let ijk = [
                    origin[0] + (n >> 6) as i32,
                    origin[1] + ((n >> 3) & 7) as i32,
                    origin[2] + (n & 7) as i32,
                ];
                out.push((ijk, *v));
            }
        }
    }
    out.sort_by_key(|&(p, _)| p);
    out
}

fn lexicographic_less(a: &[f32], b: &[f32]) -> bool {
    for (x, y) in a.iter().zip(b) {
        if x != y {
            return x < y;
        }
    }
    false
}

/// The expectations of one grid; `probes` are voxels whose values are checked (active
/// or not), `dump` the name of a file of all active voxels, written beside it.
fn expect<T: Sample>(
    grid: &Grid<T>,
    probes: &[[i32; 3]],
    index: [i32; 3],
    dump: Option<(&Path, &str)>,
) -> Value {
    let voxels = active(grid);
    let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
    let (mut min, mut max) = (T::ZERO.parts(), T::ZERO.parts());
    for (k, (p, v)) in voxels.iter().enumerate() {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
        let c = v.parts();
        if k == 0 || lexicographic_less(&c, &min) {
            min = c.clone();
        }
        if k == 0 || lexicographic_less(&max, &c) {
            max = c;
        }
    }
    let probes: Vec<Value> = probes
        .iter()
        .map(|&p| json!({ "ijk": p, "value": grid.get(p).json(), "active": !grid.get(p).is_zero() }))
        .collect();
    let t = grid.transform();
    let mut metadata = serde_json::Map::new();
    for (name, value) in grid.metadata().iter() {
        let v = match value {
            phenomena_core::vdb::MetaValue::String(s) => json!(s),
            phenomena_core::vdb::MetaValue::Float(f) => json!(f),
            other => panic!("the sample writes no {other:?}"),
        };
        metadata.insert(name.to_owned(), v);
    }
    metadata.insert("file_voxel_count".into(), json!(voxels.len()));
    metadata.insert("file_compression".into(), json!("active values"));
    // OpenVDB's empty bounding box is (max, min), which `lo` and `hi` start as.
    metadata.insert("file_bbox_min".into(), json!(lo));
    metadata.insert("file_bbox_max".into(), json!(hi));
    let mut e = json!({
        "name": grid.name(),
        "type": T::TYPE,
        "class": grid.class().as_str(),
        "active_voxel_count": voxels.len(),
        "min": if T::TYPE == "float" { json!(min[0]) } else { json!(min) },
        "max": if T::TYPE == "float" { json!(max[0]) } else { json!(max) },
        "bbox": if voxels.is_empty() { Value::Null } else { json!([lo, hi]) },
        "voxel_size": t.voxel_size_m(),
        "index_to_world": { "index": index, "world": t.index_to_world_m(index.map(f64::from)) },
        "probes": probes,
        "metadata": metadata,
    });
    if let Some((dir, file)) = dump {
        let mut bytes = Vec::new();
        for (p, v) in &voxels {
            p.iter().for_each(|c| bytes.extend_from_slice(&c.to_le_bytes()));
            v.parts().iter().for_each(|c| bytes.extend_from_slice(&c.to_le_bytes()));
        }
        std::fs::write(dir.join(file), bytes).expect("write the dump");
        e["dump"] = json!(file);
    }
    e
}

fn write(dir: &Path, name: &str, grids: &[AnyGrid<'_>], file_meta: &Metadata, expected: Vec<Value>) {
    let bytes = encode(grids, file_meta);
    std::fs::write(dir.join(format!("{name}.vdb")), &bytes).expect("write the volume");
    let file_metadata: serde_json::Map<String, Value> = file_meta
        .iter()
        .map(|(k, v)| match v {
            phenomena_core::vdb::MetaValue::String(s) => (k.to_owned(), json!(s)),
            other => panic!("the sample writes no {other:?}"),
        })
        .collect();
    let doc = json!({ "file": format!("{name}.vdb"), "file_metadata": file_metadata, "grids": expected });
    let text = serde_json::to_string_pretty(&doc).expect("json");
    std::fs::write(dir.join(format!("{name}.json")), text).expect("write the expectations");
    println!("{name}.vdb: {} bytes, {} grid(s)", bytes.len(), grids.len());
}

fn main() {
    let dir = std::env::args().nth(1).expect("usage: vdb_sample OUT_DIR");
    let dir = Path::new(&dir);
    std::fs::create_dir_all(dir).expect("create the output folder");
    let none = Metadata::new();
    let mut file_meta = Metadata::new();
    file_meta.insert("creator", "phenomena vdb_sample").expect("metadata");
    let single = write_single(dir, &none);
    write_sphere(dir, &file_meta);
    write_negative(dir, &file_meta);
    write_spread(dir, &none);
    write_flame(dir, &file_meta);
    write_random(dir, &file_meta);
    // An empty grid beside a one-voxel one.
    let unit = Transform::new(1.0, [0.0; 3]).expect("transform");
    let empty = Grid::<f32>::new("empty", unit, GridClass::FogVolume);
    let e1 = expect(&empty, &[[0, 0, 0]], [1, 1, 1], None);
    let e2 = expect(&single, &[[1, 2, 3]], [0, 0, 0], None);
    write(dir, "empty", &[AnyGrid::from(&empty), AnyGrid::from(&single)], &none, vec![e1, e2]);
}

/// `single`: one voxel, a centimetre grid offset from the world origin; returns the grid.
fn write_single(dir: &Path, none: &Metadata) -> Grid<f32> {
    let cm = Transform::new(0.01, [0.1, 0.2, 0.3]).expect("transform");
    let mut single = Grid::<f32>::new("density", cm, GridClass::FogVolume);
    single.set([1, 2, 3], 5.0);
    let e = expect(&single, &[[1, 2, 3], [1, 2, 4], [0, 0, 0]], [1, 2, 3], None);
    write(dir, "single", &[AnyGrid::from(&single)], none, vec![e]);
    single
}

/// `sphere`: a sphere of radius 20 voxels across the origin, density falling linearly
/// to 0.
fn write_sphere(dir: &Path, file_meta: &Metadata) {
    let mm = Transform::new(0.005, [-0.25, 0.0, 1.5]).expect("transform");
    let mut sphere = Grid::<f32>::new("density", mm, GridClass::FogVolume);
    sphere.insert_metadata("units", "kg/m^3").expect("metadata");
    let centre = [6, -5, 2];
    for x in -20..=20 {
        for y in -20..=20 {
            for z in -20..=20 {
                let d = ((x * x + y * y + z * z) as f32).sqrt();
                if d < 20.0 {
                    sphere.add([centre[0] + x, centre[1] + y, centre[2] + z], 1.0 - d / 20.0);
                }
            }
        }
    }
    let probes = [[6, -5, 2], [16, -5, 2], [6, 14, 2], [6, -5, -17], [26, -5, 2], [-13, -5, 2]];
    let e = expect(&sphere, &probes, [-14, 0, 7], Some((dir, "sphere.bin")));
    write(dir, "sphere", &[AnyGrid::from(&sphere)], file_meta, vec![e]);
}

/// `negative`: a vector grid at negative coordinates, with a float grid beside it.
fn write_negative(dir: &Path, file_meta: &Metadata) {
    let unit = Transform::new(1.0, [0.0; 3]).expect("transform");
    let mut emission = Grid::<[f32; 3]>::new("emission", unit, GridClass::Unknown);
    emission.insert_metadata("units", "W/m^3/sr").expect("metadata");
    let mut temperature = Grid::<f32>::new("temperature", unit, GridClass::Unknown);
    temperature.insert_metadata("units", "K").expect("metadata");
    for k in 0..40 {
        let p = [-k - 1, -2 * k - 3, -(k % 9) - 1];
        emission.set(p, [k as f32, 0.5 * k as f32 - 3.0, -(k as f32)]);
        temperature.set(p, 1500.0 + 10.0 * k as f32);
    }
    emission.set([-1, -1, -1], [0.0, 0.0, 2.5]);
    let probes = [[-1, -3, -1], [-40, -81, -4], [-1, -1, -1], [-2, -2, -2], [0, 0, 0]];
    let e1 = expect(&emission, &probes, [-40, -81, -4], Some((dir, "negative_emission.bin")));
    let e2 = expect(&temperature, &probes, [-1, -3, -1], Some((dir, "negative_temperature.bin")));
    let grids = [AnyGrid::from(&emission), AnyGrid::from(&temperature)];
    write(dir, "negative", &grids, file_meta, vec![e1, e2]);
}

/// `spread`: voxels ±5000 apart, in several root children, internal nodes and leaves.
fn write_spread(dir: &Path, none: &Metadata) {
    let unit = Transform::new(1.0, [0.0; 3]).expect("transform");
    let mut spread = Grid::<f32>::new("spread", unit, GridClass::FogVolume);
    let corners = [
        [5000, 5000, 5000],
        [-5000, 5000, -5000],
        [-5000, -5000, -5000],
        [5000, -5000, 5],
        [0, 0, 0],
        [4095, 4096, -4097],
        [-1, -1, -1],
        [127, 128, -129],
        [7, 8, -9],
    ];
    for (k, p) in corners.iter().enumerate() {
        spread.set(*p, k as f32 + 0.25);
    }
    let probes: Vec<[i32; 3]> = corners.iter().copied().chain([[5000, 5000, 5001], [1, 0, 0]]).collect();
    let e = expect(&spread, &probes, [-5000, 5000, -5000], Some((dir, "spread.bin")));
    write(dir, "spread", &[AnyGrid::from(&spread)], none, vec![e]);
}

/// `flame`: a flame-like frame, density, temperature and vector emission from the same
/// splats.
fn write_flame(dir: &Path, file_meta: &Metadata) {
    let flame_t = Transform::new(0.01, [-0.2, 0.0, -0.2]).expect("transform");
    let mut density = Grid::<f32>::new("density", flame_t, GridClass::FogVolume);
    let mut heat = Grid::<f32>::new("temperature", flame_t, GridClass::Unknown);
    let mut light = Grid::<[f32; 3]>::new("emission", flame_t, GridClass::Unknown);
    heat.insert_metadata("units", "K").expect("metadata");
    let mut s = Stream::new(3, Purpose::named("vdb_sample.flame"), 0);
    for _ in 0..3000 {
        let c = [s.below(40) as i32, s.below(120) as i32, s.below(40) as i32];
        let w = s.uniform(0.1, 1.0);
        for d in [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]] {
            let p = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
            density.add(p, w);
            heat.add(p, 1800.0 * w);
            light.add(p, [w, 0.5 * w, 0.1 * w]);
        }
    }
    let probes = [[0, 0, 0], [20, 60, 20], [39, 119, 39]];
    let e1 = expect(&density, &probes, [40, 120, 40], Some((dir, "flame_density.bin")));
    let e2 = expect(&heat, &probes, [0, 0, 0], Some((dir, "flame_temperature.bin")));
    let e3 = expect(&light, &probes, [0, 0, 0], Some((dir, "flame_emission.bin")));
    let grids = [AnyGrid::from(&density), AnyGrid::from(&heat), AnyGrid::from(&light)];
    write(dir, "flame", &grids, file_meta, vec![e1, e2, e3]);
}

/// `random`: 100,000 random voxels in a 2000³ box, every one compared after reading.
fn write_random(dir: &Path, file_meta: &Metadata) {
    let unit = Transform::new(1.0, [0.0; 3]).expect("transform");
    let mut random = Grid::<f32>::new("random", unit, GridClass::Unknown);
    let mut random3 = Grid::<[f32; 3]>::new("random3", unit, GridClass::Unknown);
    let mut s = Stream::new(5, Purpose::named("vdb_sample.random"), 0);
    while random.active_voxel_count() < 100_000 {
        for _ in 0..10_000 {
            let p = [0, 1, 2].map(|_| s.below(2000) as i32 - 1000);
            let v = s.uniform(-1.0, 1.0);
            random.set(p, v);
            random3.set(p, [v, s.uniform(-1.0, 1.0), s.next_f32()]);
        }
    }
    let probes = [[0, 0, 0], [999, 999, 999], [-1000, -1000, -1000]];
    let e1 = expect(&random, &probes, [-1000, 0, 999], Some((dir, "random.bin")));
    let e2 = expect(&random3, &probes, [0, 0, 0], Some((dir, "random3.bin")));
    write(dir, "random", &[AnyGrid::from(&random), AnyGrid::from(&random3)], file_meta, vec![e1, e2]);
}
