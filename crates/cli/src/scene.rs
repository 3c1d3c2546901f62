//! Scene files: TOML with a `[scene]` table, one phenomenon table (e.g. `[flame]`) and
//! that phenomenon's `[render]` table. Every problem is reported as `file:line:column`.

use std::fmt;
use std::path::{Path, PathBuf};

use phenomena_aurora::{AuroraConfig, RenderSettings as AuroraRenderSettings};
use phenomena_core::tonemap::{Exposure, ToneMap};
use phenomena_core::validate::{Issue, Issues};
use phenomena_flame::{FlameConfig, RenderSettings as FlameRenderSettings};
use serde::{Deserialize, Serialize};
use toml::de::{DeTable, DeValue};

/// Settings every scene shares (`[scene]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct SceneSettings {
    /// Number of frames to render.
    pub(crate) frames: u32,
    /// Image width, pixels.
    pub(crate) width: u32,
    /// Image height, pixels.
    pub(crate) height: u32,
    /// Seed of every random stream.
    pub(crate) seed: u64,
    /// Exposure compensation in stops, applied before tone mapping (PNG only).
    pub(crate) exposure_ev: f32,
    /// Tone-mapping operator for PNG output.
    pub(crate) tone_map: ToneMap,
}

impl Default for SceneSettings {
    fn default() -> Self {
        Self { frames: 120, width: 1280, height: 720, seed: 1, exposure_ev: 0.0, tone_map: ToneMap::Aces }
    }
}

impl SceneSettings {
    pub(crate) fn exposure(&self) -> Exposure {
        Exposure { ev: self.exposure_ev, tone_map: self.tone_map }
    }

    fn validate(&self, i: &mut Issues) {
        i.count("frames", u64::from(self.frames), 1..=1_000_000);
        i.count("width", u64::from(self.width), 1..=16384);
        i.count("height", u64::from(self.height), 1..=16384);
        i.range("exposure_ev", self.exposure_ev, -32.0..=32.0);
    }
}

/// A flame scene file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FlameScene {
    #[serde(default)]
    pub(crate) scene: SceneSettings,
    #[serde(default)]
    pub(crate) flame: FlameConfig,
    #[serde(default)]
    pub(crate) render: FlameRenderSettings,
}

/// An aurora scene file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct AuroraScene {
    #[serde(default)]
    pub(crate) scene: SceneSettings,
    #[serde(default)]
    pub(crate) aurora: AuroraConfig,
    #[serde(default)]
    pub(crate) render: AuroraRenderSettings,
}

/// Where a snow scene's geometry comes from (`[geometry]`): a built-in scene or a mesh
/// file (OBJ, glTF/GLB or DXF by extension, relative to the scene file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct SnowGeometry {
    /// A built-in scene (used when `mesh` is not given).
    pub(crate) builtin: phenomena_snow::mesh::Builtin,
    /// A mesh file instead.
    pub(crate) mesh: Option<PathBuf>,
    /// Scale from the file's units to metres.
    pub(crate) scale: f32,
}

impl Default for SnowGeometry {
    fn default() -> Self {
        Self { builtin: phenomena_snow::mesh::Builtin::Table, mesh: None, scale: 1.0 }
    }
}

/// A snow scene file: each frame is one time step of the snowfall.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SnowScene {
    #[serde(default)]
    pub(crate) scene: SceneSettings,
    #[serde(default)]
    pub(crate) geometry: SnowGeometry,
    #[serde(default)]
    pub(crate) snow: phenomena_snow::SnowParams,
    #[serde(default)]
    pub(crate) render: phenomena_snow::SnowRenderSettings,
}

/// A sparkle scene file (diamond dust or leaf glitter).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SparkleScene {
    #[serde(default)]
    pub(crate) scene: SceneSettings,
    #[serde(default)]
    pub(crate) sparkle: phenomena_sparkle::SparkleConfig,
    #[serde(default)]
    pub(crate) render: phenomena_sparkle::RenderSettings,
}

/// Any scene, by phenomenon.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Scene {
    Flame(Box<FlameScene>),
    Aurora(Box<AuroraScene>),
    Snow(Box<SnowScene>),
    Sparkle(Box<SparkleScene>),
}

impl Scene {
    pub(crate) fn settings(&self) -> &SceneSettings {
        match self {
            Scene::Flame(s) => &s.scene,
            Scene::Aurora(s) => &s.scene,
            Scene::Snow(s) => &s.scene,
            Scene::Sparkle(s) => &s.scene,
        }
    }

    pub(crate) fn settings_mut(&mut self) -> &mut SceneSettings {
        match self {
            Scene::Flame(s) => &mut s.scene,
            Scene::Aurora(s) => &mut s.scene,
            Scene::Snow(s) => &mut s.scene,
            Scene::Sparkle(s) => &mut s.scene,
        }
    }

    pub(crate) fn phenomenon(&self) -> &'static str {
        match self {
            Scene::Flame(_) => "flame",
            Scene::Aurora(_) => "aurora",
            Scene::Snow(_) => "snow",
            Scene::Sparkle(_) => "sparkle",
        }
    }

    /// Every problem, with field paths from the file's root (e.g. `flame.sph.k`).
    pub(crate) fn validate(&self) -> Vec<Issue> {
        let mut i = Issues::default();
        let mut scene = Issues::default();
        self.settings().validate(&mut scene);
        if let Err(e) = scene.into_result() {
            i.extend_prefixed("scene", e);
        }
        match self {
            Scene::Flame(s) => {
                if let Err(e) = s.flame.validate() {
                    i.extend_prefixed("flame", e);
                }
                if let Err(e) = s.render.validate() {
                    i.extend_prefixed("render", e);
                }
            }
            Scene::Aurora(s) => match s.aurora.validate() {
                Err(e) => i.extend_prefixed("aurora", e),
                Ok(()) => {
                    if let Err(e) = s.render.sky.validate() {
                        i.extend_prefixed("render.sky", e);
                    }
                    if let Err(e) = s.aurora.animation() {
                        i.extend_prefixed("aurora", vec![Issue::described(e.field(), e.to_string())]);
                    }
                }
            },
            Scene::Snow(s) => {
                let mut g = Issues::default();
                g.range_open_low("scale", s.geometry.scale, 0.0, 1e6);
                if let Err(e) = g.into_result() {
                    i.extend_prefixed("geometry", e);
                }
                if let Err(e) = s.snow.validate() {
                    i.extend_prefixed("snow", e);
                }
                if let Err(e) = s.render.validate() {
                    i.extend_prefixed("render", e);
                }
            }
            Scene::Sparkle(s) => {
                if let Err(e) = s.sparkle.validate() {
                    i.extend_prefixed("sparkle", e);
                }
                if let Err(e) = s.render.validate() {
                    i.extend_prefixed("render", e);
                }
            }
        }
        i.into_result().err().unwrap_or_default()
    }
}

/// The phenomena a scene file may hold, by table name.
pub(crate) const PHENOMENA: [&str; 4] = ["flame", "aurora", "snow", "sparkle"];

/// A problem at a place in a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Located {
    pub(crate) file: PathBuf,
    pub(crate) line: usize,
    pub(crate) column: usize,
    pub(crate) message: String,
}

impl fmt::Display for Located {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: {}", self.file.display(), self.line, self.column, self.message)
    }
}

/// Problems found in a scene file (at least one).
#[derive(Debug)]
pub(crate) struct SceneErrors(pub(crate) Vec<Located>);

impl fmt::Display for SceneErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (k, e) in self.0.iter().enumerate() {
            if k > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for SceneErrors {}

/// 1-based line and column (in characters) of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..text.floor_char_boundary(offset)];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Parse and validate scene text; `file` names it in messages.
pub(crate) fn parse(text: &str, file: &Path) -> Result<Scene, SceneErrors> {
    let at = |offset: usize, message: String| {
        let (line, column) = line_column(text, offset);
        Located { file: file.to_path_buf(), line, column, message }
    };
    let root = DeTable::parse(text).map_err(|e| {
        SceneErrors(vec![at(e.span().map_or(0, |s| s.start), e.message().trim().to_string())])
    })?;
    let present: Vec<&str> = PHENOMENA.iter().copied().filter(|p| root.get_ref().get(*p).is_some()).collect();
    let scene = match present.as_slice() {
        ["flame"] => deserialize_all::<FlameScene>(text).map(|s| Scene::Flame(Box::new(s))),
        ["aurora"] => deserialize_all::<AuroraScene>(text).map(|s| Scene::Aurora(Box::new(s))),
        ["snow"] => deserialize_all::<SnowScene>(text).map(|s| Scene::Snow(Box::new(s))),
        ["sparkle"] => deserialize_all::<SparkleScene>(text).map(|s| Scene::Sparkle(Box::new(s))),
        [] => {
            return Err(SceneErrors(vec![at(
                0,
                format!(
                    "no phenomenon table: a scene holds exactly one of {} (e.g. a [flame] table)",
                    PHENOMENA.map(|p| format!("[{p}]")).join(", ")
                ),
            )]));
        }
        several => {
            let second = several[1];
            let offset = root.get_ref().get(second).map_or(0, |v| v.span().start);
            return Err(SceneErrors(vec![at(
                offset,
                format!("a scene holds one phenomenon, but this file has [{}]", several.join("], [")),
            )]));
        }
    }
    .map_err(|errors| {
        SceneErrors(errors.into_iter().map(|(offset, message)| at(offset, message)).collect())
    })?;

    let issues = scene.validate();
    if issues.is_empty() {
        return Ok(scene);
    }
    Err(SceneErrors(
        issues.into_iter().map(|issue| at(locate(root.get_ref(), &issue.field), issue.to_string())).collect(),
    ))
}

/// Deserialize, collecting every unknown key and bad value rather than stopping at the
/// first: after each error the offending `key = value` is blanked out (positions kept)
/// and the text is read again. Returns (byte offset, message) per problem.
fn deserialize_all<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, Vec<(usize, String)>> {
    const MAX_ERRORS: usize = 50;
    let mut work = text.to_string();
    let mut errors: Vec<(usize, String)> = Vec::new();
    while errors.len() < MAX_ERRORS {
        match toml::from_str::<T>(&work) {
            Ok(value) if errors.is_empty() => return Ok(value),
            Ok(_) => break,
            Err(e) => {
                let offset = e.span().map_or(0, |s| s.start);
                let message = e.message().trim().to_string();
                if errors.last().is_some_and(|last| last.0 == offset && last.1 == message) {
                    break; // blanking did not remove the cause (e.g. a missing field)
                }
                errors.push((offset, message));
                let Some(range) =
                    DeTable::parse(&work).ok().and_then(|root| entry_at(root.get_ref(), offset))
                else {
                    break;
                };
                let blanked: String = work[range.clone()]
                    .chars()
                    .map(|c| if c == '\n' || c == '\r' { c } else { ' ' })
                    .collect();
                work.replace_range(range, &blanked);
                if DeTable::parse(&work).is_err() {
                    break; // blanking inside an inline table broke the syntax: stop here
                }
            }
        }
    }
    errors.sort_by_key(|e| e.0);
    Err(errors)
}

/// The byte range `key = value` of the innermost entry whose key or value contains
/// `offset`.
fn entry_at(table: &DeTable<'_>, offset: usize) -> Option<std::ops::Range<usize>> {
    for (key, value) in table.iter() {
        // Spans of header tables do not always cover their bodies: look inside first.
        let inner = match value.get_ref() {
            DeValue::Table(t) => entry_at(t, offset),
            DeValue::Array(a) => a.iter().find_map(|el| match el.get_ref() {
                DeValue::Table(t) => entry_at(t, offset),
                _ => None,
            }),
            _ => None,
        };
        if inner.is_some() {
            return inner;
        }
        let (k, v) = (key.span(), value.span());
        let whole = k.start.min(v.start)..k.end.max(v.end);
        if whole.contains(&offset) && !matches!(value.get_ref(), DeValue::Table(_)) {
            return Some(whole);
        }
    }
    None
}

/// Read and parse a scene file.
pub(crate) fn load(path: &Path) -> anyhow::Result<Scene> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read the scene file: {e}", path.display()))?;
    Ok(parse(&text, path)?)
}

/// Byte offset of the value at a dotted field path such as `flame.wind.keys[1].time_s`,
/// or of the closest enclosing item that is written in the file (a default value has no
/// place of its own).
fn locate(root: &DeTable<'_>, field: &str) -> usize {
    let mut offset = 0;
    let mut table: Option<&DeTable<'_>> = Some(root);
    let mut value: Option<&DeValue<'_>> = None;
    for segment in field.split('.') {
        let (key, index) = match segment.split_once('[') {
            Some((k, rest)) => (k, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (segment, None),
        };
        let next = match (table, value) {
            (Some(t), _) => t.get(key),
            (None, Some(v)) => v.as_table().and_then(|t| t.get(key)),
            _ => None,
        };
        let Some(item) = next else { break };
        offset = item.span().start;
        let mut v = item.get_ref();
        if let Some(k) = index {
            match v.as_array().and_then(|a| a.get(k)) {
                Some(el) => {
                    offset = el.span().start;
                    v = el.get_ref();
                }
                None => break,
            }
        }
        table = None;
        value = Some(v);
    }
    offset
}

/// Scenes shipped in `scenes/`, embedded so `demo` and `new` work anywhere.
pub(crate) mod builtin {
    /// Fig 8: the paper's flame, about 3,000 particles.
    pub(crate) const FLAME_PAPER: &str = include_str!("../../../scenes/flame-paper.toml");
    /// Fig 9: wind to the left.
    pub(crate) const FLAME_WIND_LEFT: &str = include_str!("../../../scenes/flame-wind-left.toml");
    /// Fig 10: wind to the right.
    pub(crate) const FLAME_WIND_RIGHT: &str = include_str!("../../../scenes/flame-wind-right.toml");
    /// Showcase.
    pub(crate) const FLAME_CAMPFIRE: &str = include_str!("../../../scenes/flame-campfire.toml");
    /// Thesis scene 2: an S-shaped sheet that splits (Figs 3.5, 3.10).
    pub(crate) const AURORA_SCENE2: &str = include_str!("../../../scenes/aurora-scene2.toml");
    /// The snow paper's Fig 7: snow on and under a table.
    pub(crate) const SNOW_TABLE: &str = include_str!("../../../scenes/snow-table.toml");
    pub(crate) const SPARKLE_DIAMOND_DUST: &str = include_str!("../../../scenes/sparkle-diamond-dust.toml");
    pub(crate) const SPARKLE_LEAF_GLITTER: &str = include_str!("../../../scenes/sparkle-leaf-glitter.toml");
}

#[cfg(test)]
mod tests {
    use super::*;

    fn errors(text: &str) -> Vec<String> {
        match parse(text, Path::new("s.toml")) {
            Ok(_) => Vec::new(),
            Err(e) => e.0.iter().map(|l| l.to_string()).collect(),
        }
    }

    #[test]
    fn line_and_column_are_one_based_characters() {
        assert_eq!(line_column("ab\ncdé\nx", 0), (1, 1));
        assert_eq!(line_column("ab\ncdé\nx", 3), (2, 1));
        assert_eq!(line_column("ab\ncdé\nx", 8), (3, 1));
        assert_eq!(line_column("ab\ncdé\nx", 99), (3, 2));
        assert_eq!(line_column("ab\ncdé\nx", 7), (2, 4));
    }

    #[test]
    fn syntax_errors_are_located() {
        let e = errors("[flame]\nmode = \"paper\"\nsubsteps = = 2\n");
        assert_eq!(e.len(), 1);
        assert!(e[0].starts_with("s.toml:3:"), "{e:?}");
    }

    #[test]
    fn every_unknown_key_and_bad_value_is_reported() {
        let e = errors(
            "[scene]\nwidth = 0\nframez = 3\n[flame]\nsubstepz = 2\n[flame.sph]\ngas_constant = -1\nsupport_radius_m = \"big\"\n",
        );
        assert_eq!(e.len(), 4, "{e:?}");
        assert!(e[0].starts_with("s.toml:3:1: unknown field `framez`"), "{e:?}");
        assert!(e.iter().any(|m| m.starts_with("s.toml:5:1: unknown field `substepz`")), "{e:?}");
        assert!(e.iter().any(|m| m.starts_with("s.toml:7:1: unknown field `gas_constant`")), "{e:?}");
        assert!(e.iter().any(|m| m.starts_with("s.toml:8:")), "{e:?}");
    }

    #[test]
    fn unknown_keys_are_located() {
        let e = errors("[flame]\n[flame.sph]\nsupport_radius = 0.1\n");
        assert_eq!(e.len(), 1);
        assert!(e[0].starts_with("s.toml:3:1: unknown field `support_radius`"), "{e:?}");
    }

    #[test]
    fn out_of_range_values_are_located_at_the_value() {
        let text = "[scene]\nwidth = 0\n[flame.sph]\ngas_constant_m2_s2 = -2.0\n[[flame.wind.keys]]\ntime_s = 1\nforce_n_m3 = [0, 0, 0]\n[[flame.wind.keys]]\ntime_s = 0.5\nforce_n_m3 = [1, 0, 0]\n";
        let e = errors(text);
        assert_eq!(e.len(), 3, "{e:?}");
        assert_eq!(e[0], "s.toml:2:9: scene.width = 0: expected an integer in [1, 16384]");
        assert!(e[1].starts_with("s.toml:4:22: flame.sph.gas_constant_m2_s2 = -2"), "{e:?}");
        assert!(e[2].starts_with("s.toml:9:10: flame.wind.keys[1].time_s = 0.5"), "{e:?}");
    }

    #[test]
    fn phenomenon_table_is_required_and_unique() {
        let e = errors("[scene]\nframes = 3\n");
        assert!(e[0].contains("no phenomenon table"), "{e:?}");
        let e = errors("[flmae]\n");
        assert!(e[0].contains("no phenomenon table"), "{e:?}");
    }

    #[test]
    fn the_readme_scene_example_is_valid() {
        let readme = include_str!("../../../README.md");
        let start = readme.find("```toml\n").expect("README has a TOML example") + 8;
        let end = start + readme[start..].find("```").expect("closed");
        if let Err(e) = parse(&readme[start..end], Path::new("README.md")) {
            panic!("{e}");
        }
    }

    #[test]
    fn shipped_scenes_are_valid() {
        for (name, text) in [
            ("flame-paper", builtin::FLAME_PAPER),
            ("flame-wind-left", builtin::FLAME_WIND_LEFT),
            ("flame-wind-right", builtin::FLAME_WIND_RIGHT),
            ("flame-campfire", builtin::FLAME_CAMPFIRE),
        ] {
            if let Err(e) = parse(text, Path::new(name)) {
                panic!("{e}");
            }
        }
    }
}
