//! The studio's parameter controls, derived from the scene types themselves so they
//! can never disagree with `phenomena render`: every number, switch, choice and vector
//! of a phenomenon's scene becomes a control, its valid range the typed
//! [`Expected`] the scene's own validation gives a far out-of-range value, and the
//! choices of an enum the deserialiser's "expected one of" list. Units come from the
//! field names' suffixes (`_m`, `_deg`, `_n_m3`...), which the page turns into labels.

use std::collections::BTreeMap;

use phenomena_core::validate::Expected;
use phenomena_scene::registry::{self, Entry};
use serde::Serialize;
use serde_json::Value;

use phenomena_scene::set_path;

/// Parameters each tab shows first (the rest follow, grouped by table).
const FEATURED: &[(&str, &[&str])] = &[
    (
        "flame",
        &[
            "flame.emitter.temperature_k",
            "flame.emitter.rate_per_s",
            "render.shimmer.enabled",
            "flame.mode",
            "scene.seed",
        ],
    ),
    ("aurora", &["render.view", "aurora.motion.particles", "aurora.field.charges", "scene.seed"]),
    (
        "snow",
        &[
            "geometry.builtin",
            "snow.main_tilt_deg",
            "snow.spread_deg",
            "snow.rate_cm_per_h",
            "snow.repose_deg",
            "render.view",
            "scene.seed",
        ],
    ),
    (
        "sparkle",
        &[
            "sparkle.light.azimuth_deg",
            "sparkle.light.elevation_deg",
            "sparkle.phong.exponent_n",
            "sparkle.phong.threshold_i_e",
            "scene.seed",
        ],
    ),
    (
        "shot",
        &[
            "render.sun.azimuth_deg",
            "render.sun.elevation_deg",
            "render.flame.intensity",
            "render.snow.sun_strength",
            "render.sparkle.glint_gain",
            "scene.seed",
        ],
    ),
];

/// One control.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct Control {
    /// Dotted path in the scene (`flame.emitter.rate_per_s`).
    pub(crate) path: String,
    /// `number`, `integer`, `bool`, `choice`, `vector` or `text`.
    pub(crate) kind: &'static str,
    /// What validation accepts, in its words (e.g. `a value in [0, 1]`), if it checks.
    pub(crate) valid: Option<String>,
    /// Lowest valid value (of each component, for a vector).
    pub(crate) min: Option<f64>,
    /// Highest valid value.
    pub(crate) max: Option<f64>,
    /// Whether `min` itself is excluded.
    pub(crate) min_open: bool,
    /// The choices of a `choice`.
    pub(crate) choices: Vec<String>,
}

/// Controls per phenomenon.
#[derive(Debug, Serialize)]
pub(crate) struct Catalogue {
    controls: BTreeMap<&'static str, Vec<Control>>,
}

impl Catalogue {
    /// Probe the scene types through the first shipped scene of each phenomenon.
    pub(crate) fn build() -> Self {
        let mut controls = BTreeMap::new();
        for p in registry::PHENOMENA {
            let Some(s) = phenomena_scene::shipped::SHIPPED.iter().find(|s| s.phenomenon == p.name()) else {
                continue;
            };
            let Ok(scene) = s.scene() else { continue };
            controls.insert(p.name(), probe(*p, &scene.to_json()));
        }
        Self { controls }
    }

    /// The featured paths per phenomenon.
    pub(crate) fn featured(&self) -> BTreeMap<&'static str, Vec<&'static str>> {
        FEATURED.iter().map(|(p, paths)| (*p, paths.to_vec())).collect()
    }

    #[cfg(test)]
    pub(crate) fn of(&self, phenomenon: &str) -> &[Control] {
        self.controls.get(phenomenon).map_or(&[], Vec::as_slice)
    }
}

/// Every control of a scene's JSON form.
fn probe(p: Entry, root: &Value) -> Vec<Control> {
    let mut out = Vec::new();
    walk(p, root, root, String::new(), &mut out);
    out
}

fn walk(p: Entry, root: &Value, v: &Value, path: String, out: &mut Vec<Control>) {
    let join = |k: &str| if path.is_empty() { k.to_string() } else { format!("{path}.{k}") };
    match v {
        Value::Object(map) => {
            for (k, child) in map {
                walk(p, root, child, join(k), out);
            }
        }
        Value::Bool(_) => out.push(control(&path, "bool", None, Vec::new())),
        Value::Number(n) => {
            let integer = n.is_u64() || n.is_i64();
            let candidates: &[Value] = if integer {
                &[Value::from(0), Value::from(u64::from(u32::MAX)), Value::from(65_535)]
            } else {
                &[Value::from(1e30), Value::from(-1e30)]
            };
            let valid = range_of(p, root, &path, candidates);
            out.push(control(&path, if integer { "integer" } else { "number" }, valid, Vec::new()));
        }
        Value::String(_) => {
            let choices = choices_of(p, root, &path);
            let kind = if choices.is_empty() { "text" } else { "choice" };
            out.push(control(&path, kind, None, choices));
        }
        Value::Array(items) if (2..=4).contains(&items.len()) && items.iter().all(Value::is_number) => {
            let huge = Value::Array(vec![Value::from(1e30); items.len()]);
            let valid = range_of(p, root, &path, &[huge]);
            out.push(control(&path, "vector", valid, Vec::new()));
        }
        // Lists of keyframes, strokes and operations have their own editors (or the
        // scene file); optional values that are absent have no form to show.
        _ => {}
    }
}

fn control(path: &str, kind: &'static str, valid: Option<Expected>, choices: Vec<String>) -> Control {
    let (min, max, min_open) = match &valid {
        Some(Expected::Range { min, max, min_open }) => (Some(*min), Some(*max), *min_open),
        Some(Expected::Count { min, max }) => (Some(*min as f64), Some(*max as f64), false),
        Some(Expected::Vector { max_abs }) => (Some(-max_abs), Some(*max_abs), false),
        _ => (None, None, false),
    };
    Control { path: path.to_string(), kind, valid: valid.map(|v| v.to_string()), min, max, min_open, choices }
}

/// What validation expects at `path`, told by a far out-of-range value.
fn range_of(p: Entry, root: &Value, path: &str, candidates: &[Value]) -> Option<Expected> {
    for c in candidates {
        let mut v = root.clone();
        if set_path(&mut v, path, c.clone()).is_err() {
            continue;
        }
        let Ok(s) = p.scene_from_json(v) else { continue };
        if let Some(i) = s.validate().into_iter().find(|i| i.field == path) {
            return Some(i.expected);
        }
    }
    None
}

/// The variants the deserialiser lists for an unknown value at `path`.
fn choices_of(p: Entry, root: &Value, path: &str) -> Vec<String> {
    let mut v = root.clone();
    if set_path(&mut v, path, Value::from("\u{1}")).is_err() {
        return Vec::new();
    }
    let Err(message) = p.scene_from_json(v) else { return Vec::new() };
    let Some(list) = message.split_once("expected").map(|(_, rest)| rest) else { return Vec::new() };
    list.split('`').skip(1).step_by(2).map(str::to_string).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_featured_path_is_a_control() {
        let c = Catalogue::build();
        for (p, paths) in FEATURED {
            for path in *paths {
                assert!(c.of(p).iter().any(|x| x.path == *path), "{p}: {path} is not a control");
            }
        }
    }

    #[test]
    fn ranges_and_choices_come_from_the_scene_types() {
        let c = Catalogue::build();
        let find = |p: &str, path: &str| c.of(p).iter().find(|x| x.path == path).cloned().unwrap();
        let w = find("flame", "scene.width");
        assert_eq!((w.kind, w.min, w.max), ("integer", Some(1.0), Some(16384.0)), "{w:?}");
        let mode = find("flame", "flame.mode");
        assert_eq!(mode.choices, ["paper", "extended"]);
        let tm = find("sparkle", "scene.tone_map");
        assert_eq!(tm.kind, "choice");
        assert!(tm.choices.contains(&"aces".to_string()), "{tm:?}");
        assert_eq!(find("flame", "render.shimmer.enabled").kind, "bool");
        assert_eq!(find("flame", "flame.emitter.position_m").kind, "vector");
        let open = find("flame", "render.splat_radius_scale");
        assert!(open.min_open && open.min == Some(0.0), "{open:?}");
    }

    #[test]
    fn every_range_admits_its_bounds() {
        // Each control's advertised bounds are values its scene accepts.
        let c = Catalogue::build();
        for p in registry::PHENOMENA {
            let s = phenomena_scene::shipped::SHIPPED.iter().find(|s| s.phenomenon == p.name()).unwrap();
            let root = s.scene().unwrap().to_json();
            for ctl in c.of(p.name()) {
                let (Some(lo), Some(hi)) = (ctl.min, ctl.max) else { continue };
                if ctl.kind != "number" && ctl.kind != "integer" {
                    continue;
                }
                // Only closed ends are admitted values: `(0, 1]` excludes 0.
                let ends = [(lo, !ctl.min_open), (hi, true)];
                for x in ends.iter().filter(|e| e.1).map(|e| e.0) {
                    let mut v = root.clone();
                    let value = if ctl.kind == "integer" { Value::from(x as u64) } else { Value::from(x) };
                    set_path(&mut v, &ctl.path, value).unwrap();
                    let s = p.scene_from_json(v).unwrap();
                    // Rules across fields (e.g. rate × frame time) may still refuse a
                    // bound; the advertised range itself must not.
                    let bad: Vec<_> = s
                        .validate()
                        .into_iter()
                        .filter(|i| i.field == ctl.path && Some(i.expected.to_string()) == ctl.valid)
                        .collect();
                    assert!(bad.is_empty(), "{}: {} = {x} refused: {bad:?}", p.name(), ctl.path);
                }
            }
        }
    }
}
