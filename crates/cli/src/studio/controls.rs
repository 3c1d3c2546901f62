//! The studio's parameter controls, derived from the scene types themselves so they
//! can never disagree with `phenomena render`: every number, switch, choice and vector
//! of a phenomenon's scene becomes a control, its valid range read off the scene's own
//! `validate()` (the message a far out-of-range value gets) and the choices of an enum
//! off the deserialiser's "expected one of" message. Units come from the field names'
//! suffixes (`_m`, `_deg`, `_n_m3`...), which the page turns into labels.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;
use serde_json::Value;

use super::session::{scene_from_json, scene_json, set_path};
use crate::scene;

/// A shipped scene the studio offers.
pub(crate) struct Builtin {
    /// File name in `scenes/` without `.toml`.
    pub(crate) name: &'static str,
    /// Its phenomenon.
    pub(crate) phenomenon: &'static str,
    /// The file's text.
    pub(crate) text: &'static str,
}

macro_rules! shipped {
    ($name:literal, $phenomenon:literal) => {
        Builtin {
            name: $name,
            phenomenon: $phenomenon,
            text: include_str!(concat!("../../../../scenes/", $name, ".toml")),
        }
    };
}

/// Shipped scenes, the first of each phenomenon being the one its tab opens with.
pub(crate) const BUILTINS: &[Builtin] = &[
    shipped!("flame-paper", "flame"),
    shipped!("flame-wind-left", "flame"),
    shipped!("flame-campfire", "flame"),
    shipped!("aurora-scene2", "aurora"),
    shipped!("aurora-scene1", "aurora"),
    shipped!("aurora-scene3", "aurora"),
    shipped!("snow-table", "snow"),
    shipped!("snow-primitives", "snow"),
    shipped!("snow-village", "snow"),
    shipped!("sparkle-diamond-dust", "sparkle"),
    shipped!("sparkle-leaf-glitter", "sparkle"),
    shipped!("sparkle-sun-pillar", "sparkle"),
    shipped!("sparkle-paper", "sparkle"),
];

/// A shipped scene by name.
pub(crate) fn builtin(name: &str) -> Option<&'static Builtin> {
    BUILTINS.iter().find(|b| b.name == name)
}

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
];

/// One control.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct Control {
    /// Dotted path in the scene (`flame.emitter.rate_per_s`).
    pub(crate) path: String,
    /// `number`, `integer`, `bool`, `choice`, `vector` or `text`.
    pub(crate) kind: &'static str,
    /// What `validate()` accepts, in its words (e.g. `a value in [0, 1]`), if it checks.
    pub(crate) valid: Option<String>,
    /// Bounds parsed from `valid`, for the input's min and max.
    pub(crate) min: Option<f64>,
    /// See `min`.
    pub(crate) max: Option<f64>,
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
        for p in scene::PHENOMENA {
            let Some(b) = BUILTINS.iter().find(|b| b.phenomenon == p) else { continue };
            let Ok(s) = scene::parse(b.text, Path::new(b.name)) else { continue };
            controls.insert(p, probe(p, &scene_json(&s)));
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
fn probe(phenomenon: &str, root: &Value) -> Vec<Control> {
    let mut out = Vec::new();
    walk(phenomenon, root, root, String::new(), &mut out);
    out
}

fn walk(phenomenon: &str, root: &Value, v: &Value, path: String, out: &mut Vec<Control>) {
    let join = |k: &str| if path.is_empty() { k.to_string() } else { format!("{path}.{k}") };
    match v {
        Value::Object(map) => {
            for (k, child) in map {
                walk(phenomenon, root, child, join(k), out);
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
            let valid = range_of(phenomenon, root, &path, candidates);
            out.push(control(&path, if integer { "integer" } else { "number" }, valid, Vec::new()));
        }
        Value::String(_) => {
            let choices = choices_of(phenomenon, root, &path);
            let kind = if choices.is_empty() { "text" } else { "choice" };
            out.push(control(&path, kind, None, choices));
        }
        Value::Array(items) if (2..=4).contains(&items.len()) && items.iter().all(Value::is_number) => {
            let huge = Value::Array(vec![Value::from(1e30); items.len()]);
            let valid = range_of(phenomenon, root, &path, &[huge]);
            out.push(control(&path, "vector", valid, Vec::new()));
        }
        // Lists of keyframes, strokes and operations have their own editors (or the
        // scene file); optional values that are absent have no form to show.
        _ => {}
    }
}

fn control(path: &str, kind: &'static str, valid: Option<String>, choices: Vec<String>) -> Control {
    let (min, max) = valid.as_deref().and_then(bounds).unzip();
    Control { path: path.to_string(), kind, valid, min, max, choices }
}

/// `[lo, hi]` (or `(lo, hi]` etc.) in a validator's words.
fn bounds(text: &str) -> Option<(f64, f64)> {
    let open = text.find(['[', '('])?;
    let close = open + text[open..].find([']', ')'])?;
    let (lo, hi) = text[open + 1..close].split_once(',')?;
    Some((lo.trim().parse().ok()?, hi.trim().parse().ok()?))
}

/// What the validator says about a far out-of-range value at `path`.
fn range_of(phenomenon: &str, root: &Value, path: &str, candidates: &[Value]) -> Option<String> {
    let field = path.split_once('.').map_or(path, |(_, rest)| rest);
    let table = path.split('.').next().unwrap_or_default();
    for c in candidates {
        let mut v = root.clone();
        if set_path(&mut v, path, c.clone()).is_err() {
            continue;
        }
        let Ok(s) = scene_from_json(phenomenon, v) else { continue };
        let issues = s.validate();
        // Scene-level issues carry the full path; the phenomenon's own tables are
        // prefixed by their table name.
        if let Some(i) = issues.iter().find(|i| i.field == path || (i.field == field && table == phenomenon))
        {
            return Some(i.expected.clone());
        }
    }
    None
}

/// The variants the deserialiser lists for an unknown value at `path`.
fn choices_of(phenomenon: &str, root: &Value, path: &str) -> Vec<String> {
    let mut v = root.clone();
    if set_path(&mut v, path, Value::from("\u{1}")).is_err() {
        return Vec::new();
    }
    let Err(message) = scene_from_json(phenomenon, v) else { return Vec::new() };
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
    }

    #[test]
    fn every_range_admits_its_bounds() {
        // Each control's advertised bounds are values its scene accepts.
        let c = Catalogue::build();
        for p in scene::PHENOMENA {
            let b = BUILTINS.iter().find(|b| b.phenomenon == p).unwrap();
            let root = scene_json(&scene::parse(b.text, Path::new(b.name)).unwrap());
            for ctl in c.of(p) {
                let (Some(lo), Some(hi)) = (ctl.min, ctl.max) else { continue };
                if ctl.kind != "number" && ctl.kind != "integer" {
                    continue;
                }
                // Only closed ends are admitted values: `(0, 1]` excludes 0.
                let text = ctl.valid.as_deref().unwrap_or_default();
                let closed_lo = text.contains('[');
                let closed_hi = text.contains(']');
                let ends = [(lo, closed_lo), (hi, closed_hi)];
                for x in ends.iter().filter(|e| e.1).map(|e| e.0) {
                    let mut v = root.clone();
                    let value = if ctl.kind == "integer" { Value::from(x as u64) } else { Value::from(x) };
                    set_path(&mut v, &ctl.path, value).unwrap();
                    let s = scene_from_json(p, v).unwrap();
                    // Rules across fields (e.g. rate × frame time) may still refuse a
                    // bound; the advertised range itself must not.
                    let bad: Vec<_> = s
                        .validate()
                        .into_iter()
                        .filter(|i| ctl.path.ends_with(&i.field) && Some(&i.expected) == ctl.valid.as_ref())
                        .collect();
                    assert!(bad.is_empty(), "{p}: {} = {x} refused: {bad:?}", ctl.path);
                }
            }
        }
    }
}
