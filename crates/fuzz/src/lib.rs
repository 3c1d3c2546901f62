//! Fuzz targets: each takes any bytes and must neither panic nor hang, whatever they
//! hold. They run under AFL++ through `cargo afl` (stable Rust), and the corpus they
//! grew is committed in `corpus/<target>/` and replayed by `tests/replay.rs` as an
//! ordinary test.
//!
//! - [`scene`]: a scene file's text, as `phenomena validate` reads it: parse, validate,
//!   the constructors' checks and the estimate (no simulation is built), and a saved
//!   scene reads back the same.
//! - [`obj`], [`gltf`], [`dxf`]: the snow's mesh loaders, and for glTF the buffer URIs
//!   as the scene layer resolves them (relative references, `data:` URIs).
//! - [`checkpoint`]: checkpoint files, and any bytes as each phenomenon's state.
//! - [`air`]: the three tables `export aurora-profile --air` reads.
//! - [`studio`]: sequences of the studio's edits (the messages a page sends that change
//!   a scene: shipped scenes, parameter sets, aurora editor operations), each followed by
//!   the checks the studio makes before it builds a preview.
//!
//! Running one (AFL++ from `cargo install cargo-afl`; see `crates/fuzz/README.md`):
//!
//! ```sh
//! CARGO_TARGET_DIR=target/afl cargo afl build --release -p phenomena-fuzz --features afl --bins
//! cargo afl fuzz -i crates/fuzz/corpus/scene -o target/fuzz/scene target/afl/release/fuzz-scene
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use arbitrary::{Arbitrary, Unstructured};
use phenomena_aurora::editor::{self, Drawn, EditOp};
use phenomena_aurora::shape::PointRef;
use phenomena_scene::aurora::AuroraScene;
use phenomena_scene::{Assets, Limits, Scene};
use serde_json::{Value, json};

/// A budget small enough that estimates of absurd scenes are refused rather than run.
const LIMITS: Limits = Limits { memory_bytes: 1 << 30 };

/// A scene file's text, as `validate` reads it.
pub fn scene(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(scene) = phenomena_scene::parse(text, "fuzz.toml") else { return };
    let _ = scene.check(&Assets::none(), &LIMITS);
    // What the studio saves reads back as the same scene.
    let saved = scene.to_toml().expect("a parsed scene writes as TOML");
    let back = phenomena_scene::parse(&saved, "saved.toml").expect("a saved scene reads back");
    assert_eq!(back, scene, "a saved scene reads back the same");
}

/// OBJ bytes.
pub fn obj(data: &[u8]) {
    let _ = phenomena_snow::load::obj(data, 1.0);
}

/// DXF bytes.
pub fn dxf(data: &[u8]) {
    let _ = phenomena_snow::load::dxf(data, 1.0);
}

/// glTF or GLB bytes, their buffer URIs resolved by the scene layer's rules among a few
/// files held in memory (the bytes themselves as `buf.bin` beside the glTF).
pub fn gltf(data: &[u8]) {
    let files = BTreeMap::from([
        ("meshes/m.gltf".to_string(), Vec::new()),
        ("meshes/buf.bin".to_string(), data.to_vec()),
        ("top.bin".to_string(), data.iter().rev().copied().collect()),
    ]);
    let assets = Assets::Memory(files);
    let from = Path::new("meshes/m.gltf");
    let _ = phenomena_snow::load::gltf(
        data,
        |uri| assets.read_referenced("geometry.mesh", from, uri).map_err(|e| e.to_string()),
        1.0,
    );
}

/// Checkpoint bytes, as a render reads them: the header on its own (what a reader checks
/// before reading the rest), then the whole file; and, wrapped in a valid checkpoint of a
/// small scene of the phenomenon the first byte picks, the rest as a simulation's state,
/// which must be refused or restored, never panic.
pub fn checkpoint(data: &[u8]) {
    use phenomena_scene::checkpoint;
    let _ = checkpoint::read_header(data);
    let _ = checkpoint::open(data);
    let Some((&pick, state)) = data.split_first() else { return };
    RUNNERS.with(|runners| {
        let mut runners = runners.borrow_mut();
        let k = usize::from(pick) % runners.len();
        let Some(runner) = runners[k].as_mut() else { return };
        let Ok(bytes) = checkpoint::encode(&runner.checkpoint_header(), &RawState(state)) else { return };
        let _ = runner.restore(&bytes);
    });
}

/// Bytes that serialise as themselves: postcard writes a byte slice as its length and
/// the bytes, so the state is what follows the length.
struct RawState<'a>(&'a [u8]);

impl serde::Serialize for RawState<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        let mut t = s.serialize_tuple(self.0.len())?;
        for b in self.0 {
            t.serialize_element(b)?;
        }
        t.end()
    }
}

/// Small scenes of each phenomenon whose runners take the fuzzed states (the corpus's
/// `seed-state-K` are states of scene K after one frame).
const SMALL_SCENES: [&str; 4] = [
    "[scene]\nframes = 2\nwidth = 16\nheight = 16\n[flame]\n[flame.emitter]\nrate_per_s = 600.0\n",
    "[scene]\nframes = 2\nwidth = 16\nheight = 16\n[aurora]\n[aurora.plane]\ncells = [16, 16]\n[aurora.motion]\nparticles = 200\n",
    "[scene]\nframes = 2\nwidth = 16\nheight = 16\n[snow]\nmap_resolution = 16\nshadow_resolution = 16\ndirections = 2\n[geometry]\nbuiltin = \"table\"\n",
    "[scene]\nframes = 2\nwidth = 16\nheight = 16\n[sparkle]\n[sparkle.population]\nkind = \"diamond-dust\"\nbox_min_m = [-2.0, 0.0, -4.0]\nbox_max_m = [2.0, 2.0, 0.0]\ndensity_per_m3 = 5000.0\n",
];

thread_local! {
    static RUNNERS: std::cell::RefCell<Vec<Option<phenomena_scene::Runner>>> = std::cell::RefCell::new(
        SMALL_SCENES
            .iter()
            .map(|text| {
                let scene = phenomena_scene::parse(text, "small.toml").ok()?;
                phenomena_scene::Runner::with_limits(&scene, &Assets::none(), &LIMITS).ok()
            })
            .collect(),
    );
}

/// `export aurora-profile --air` tables: the bytes split at `0xFF` into the neutral
/// table, the minor species and the night ionosphere. Tables that are accepted must
/// give a column whose emission is finite and not negative at every altitude.
pub fn air(data: &[u8]) {
    use phenomena_aurora::atmosphere::Atmosphere;
    use phenomena_aurora::deposition::{ColumnModel, Precipitation, Yields};
    let mut parts = data.split(|&b| b == 0xFF).map(|p| std::str::from_utf8(p).unwrap_or(""));
    let (Some(neutral), Some(minor), Some(ionosphere)) = (parts.next(), parts.next(), parts.next()) else {
        return;
    };
    // Bounded work: the column is solved at every row of the table.
    if neutral.lines().count() > 2000 {
        return;
    }
    let Ok(air) = Atmosphere::from_tables(neutral, minor, ionosphere) else { return };
    let column = ColumnModel::new(&air, &Precipitation::default(), &Yields::default());
    for line in phenomena_aurora::emission::Line::ALL {
        for (z, v) in column.altitudes_km().iter().zip(column.volume_emission(line)) {
            assert!(v.is_finite() && *v >= 0.0, "{line:?} at {z} km: {v}");
        }
    }
}

/// One edit a studio page can send.
#[derive(Debug, Arbitrary)]
enum Edit {
    /// Load a shipped scene (by index into the registry's list).
    Builtin(u8),
    /// Set a parameter: a path of the scene (by index into its leaves) to a value.
    Set { path: u16, value: Scalar },
    /// An aurora editor operation.
    Aurora(AuroraEdit),
}

/// A value a control can send.
#[derive(Debug, Arbitrary)]
enum Scalar {
    Int(i64),
    Float(f64),
    Bool(bool),
    Text(String),
    Vector(Vec<f32>),
}

impl Scalar {
    fn json(&self) -> Value {
        match self {
            Scalar::Int(v) => json!(v),
            Scalar::Float(v) => json!(v),
            Scalar::Bool(v) => json!(v),
            Scalar::Text(v) => json!(v),
            Scalar::Vector(v) => json!(v),
        }
    }
}

/// The editor's operations, with any numbers.
#[derive(Debug, Arbitrary)]
enum AuroraEdit {
    Stroke { keyframe: u8, points: Vec<(f32, f32)> },
    Split { keyframe: u32, sheet: u32, point: u32 },
    Merge { keyframe: u32, a: (u32, u32), b: (u32, u32) },
    AddKeyframe { frame: u32 },
    MoveKeyframe { keyframe: u8, frame: u32 },
    DeleteKeyframe { keyframe: u8 },
    Clear,
}

impl AuroraEdit {
    fn op(&self) -> EditOp {
        let point = |(sheet, point): (u32, u32)| PointRef { sheet, point };
        match self {
            AuroraEdit::Stroke { keyframe, points } => EditOp::Stroke {
                keyframe: usize::from(*keyframe),
                points: points.iter().map(|&(x, z)| [x, z]).collect(),
            },
            &AuroraEdit::Split { keyframe, sheet, point } => EditOp::Split { keyframe, sheet, point },
            &AuroraEdit::Merge { keyframe, a, b } => EditOp::Merge { keyframe, a: point(a), b: point(b) },
            &AuroraEdit::AddKeyframe { frame } => EditOp::AddKeyframe { frame },
            &AuroraEdit::MoveKeyframe { keyframe, frame } => {
                EditOp::MoveKeyframe { keyframe: usize::from(keyframe), frame }
            }
            &AuroraEdit::DeleteKeyframe { keyframe } => {
                EditOp::DeleteKeyframe { keyframe: usize::from(keyframe) }
            }
            AuroraEdit::Clear => EditOp::Clear,
        }
    }
}

/// The dotted paths of every leaf of a scene's JSON form (what the studio's controls
/// set).
fn leaves(v: &Value, path: String, out: &mut Vec<String>) {
    match v {
        Value::Object(map) => {
            for (k, child) in map {
                let p = if path.is_empty() { k.clone() } else { format!("{path}.{k}") };
                leaves(child, p, out);
            }
        }
        _ => out.push(path),
    }
}

/// A sequence of studio edits from the bytes, each applied as the studio applies it
/// and followed by the checks it makes before building a preview.
pub fn studio(data: &[u8]) {
    let mut u = Unstructured::new(data);
    let Ok(edits) = Vec::<Edit>::arbitrary(&mut u) else { return };
    let mut scene: Scene = match phenomena_scene::shipped::SHIPPED.first().map(|s| s.scene()) {
        Some(Ok(s)) => s,
        _ => return,
    };
    let mut drawn = Drawn::default();
    for edit in edits.iter().take(32) {
        match edit {
            Edit::Builtin(k) => {
                let shipped = &phenomena_scene::shipped::SHIPPED
                    [usize::from(*k) % phenomena_scene::shipped::SHIPPED.len()];
                scene = shipped.scene().expect("shipped scenes are valid");
                drawn = scene.get::<AuroraScene>().map(|a| Drawn::of(&a.aurora)).unwrap_or_default();
            }
            Edit::Set { path, value } => {
                let mut paths = Vec::new();
                leaves(&scene.to_json(), String::new(), &mut paths);
                let path = &paths[usize::from(*path) % paths.len()];
                if let Ok(next) = scene.with_value(path, value.json())
                    && next.validate().is_empty()
                {
                    scene = next;
                }
            }
            Edit::Aurora(op) => {
                if let Some(a) = scene.get_mut::<AuroraScene>() {
                    let _ = editor::edit(&mut a.aurora, &mut drawn, op.op());
                    let _ = editor::view(&a.aurora, &drawn);
                }
            }
        }
        if scene.validate().is_empty() {
            // What the studio runs before building a preview (at a preview's size).
            let mut preview = scene.clone();
            let s = preview.settings_mut();
            (s.width, s.height) = (64, 36);
            let _ = preview.check(&Assets::none(), &LIMITS);
        }
    }
}
