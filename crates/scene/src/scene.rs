//! [`Scene`]: a parsed scene file of any phenomenon, with typed access for code that
//! knows which one it holds.

use std::fmt;
use std::path::Path;
use std::sync::Arc;

use phenomena_core::validate::{Issue, Issues};
use serde_json::Value;

use crate::assets::Assets;
use crate::budget::Estimate;
use crate::budget::{Limits, Report};
use crate::entry::{BuiltBox, Entry, FileBox};
use crate::error::BuildError;
use crate::phenomenon::{Phenomenon, View};
use crate::settings::SceneSettings;
use crate::source::{Located, Source};

/// A scene of any phenomenon: its file struct beside the registry entry that knows its
/// type.
pub struct Scene {
    entry: Entry,
    file: FileBox,
    /// The file it was read from, to locate later problems.
    source: Option<Arc<Source>>,
}

impl Scene {
    /// A scene holding `file`.
    pub fn new<P: Phenomenon>(file: P) -> Self {
        Self { entry: Entry::of::<P>(), file: Box::new(file), source: None }
    }

    /// A scene of `entry` holding `file` (made by that entry).
    pub(crate) fn from_parts(entry: Entry, file: FileBox, source: Option<Source>) -> Self {
        Self { entry, file, source: source.map(Arc::new) }
    }

    /// This scene as read from `source` (its problems located there).
    pub(crate) fn with_source(mut self, source: Source) -> Self {
        self.source = Some(Arc::new(source));
        self
    }

    /// Its phenomenon.
    pub fn phenomenon(&self) -> Entry {
        self.entry
    }

    /// The `[scene]` table.
    pub fn settings(&self) -> &SceneSettings {
        self.entry.ops().settings(&*self.file)
    }

    /// The `[scene]` table, to change (command-line overrides: size, seed). Problems
    /// are still located in the file the scene was read from, whose other keys this
    /// does not move.
    pub fn settings_mut(&mut self) -> &mut SceneSettings {
        self.entry.ops().settings_mut(&mut *self.file)
    }

    /// Every problem, with field paths from the file's root (`flame.sph.k`).
    pub fn validate(&self) -> Vec<Issue> {
        let mut i = Issues::default();
        self.settings().validate(&mut i);
        self.entry.ops().validate(&*self.file, &mut i);
        i.into_result().err().unwrap_or_default()
    }

    /// The view drawn.
    pub fn view(&self) -> &'static str {
        self.entry.ops().view(&*self.file)
    }

    /// Draw `view`; a view the phenomenon cannot draw is refused with the ones it can.
    pub fn set_view(&mut self, view: &str) -> Result<(), String> {
        let p = self.phenomenon();
        if !p.views().iter().any(|v| v.name == view) {
            let names: Vec<&str> = p.views().iter().map(|v: &View| v.name).collect();
            return Err(format!("`{view}` is not a {} view: use {}", p.name(), names.join(" or ")));
        }
        // As for `settings_mut`, the file still locates problems with other keys.
        self.entry.ops().set_view(&mut *self.file, view);
        Ok(())
    }

    /// Seconds of simulated time per frame.
    pub fn frame_time_s(&self) -> f64 {
        self.entry.ops().frame_time_s(&*self.file)
    }

    /// Why a frame's image depends on the frames rendered before it, if it does
    /// ([`Phenomenon::render_memory`]).
    pub fn render_memory(&self) -> Option<&'static str> {
        self.entry.ops().render_memory(&*self.file)
    }

    /// Draw the phenomenon's light alone over black (for flipbooks); refused for a
    /// phenomenon without [`crate::phenomenon::Capability::EmissionOnly`].
    pub fn emission_only(&mut self) -> Result<(), String> {
        if !self.entry.can(crate::phenomenon::Capability::EmissionOnly) {
            return Err(format!("{} scenes cannot be drawn as light alone over black", self.entry.name()));
        }
        self.source = None;
        self.entry.ops().emission_only(&mut *self.file);
        Ok(())
    }

    /// The scene as JSON (the form a front end edits; [`Entry::scene_from_json`] reads it).
    pub fn to_json(&self) -> Value {
        self.entry.ops().to_json(&*self.file)
    }

    /// The scene as a TOML file that reads back to the same scene.
    pub fn to_toml(&self) -> Result<String, String> {
        self.entry.ops().to_toml(&*self.file)
    }

    /// This scene with the value at dotted path `path` (`flame.emitter.rate_per_s`; no
    /// array indices) set to `value` (JSON), read back through the phenomenon's types
    /// (not validated). Setting a tagged table's `kind` replaces the whole table by
    /// `{kind = value}`, so the new variant starts from its defaults.
    pub fn with_value(&self, path: &str, value: Value) -> Result<Scene, String> {
        let mut json = self.to_json();
        set_path(&mut json, path, value)?;
        self.phenomenon().scene_from_json(json)
    }

    /// The phenomenon's file struct, when it is `P`.
    pub fn get<P: Phenomenon>(&self) -> Option<&P> {
        self.file.downcast_ref()
    }

    /// The phenomenon's file struct, to change, when it is `P`.
    pub fn get_mut<P: Phenomenon>(&mut self) -> Option<&mut P> {
        self.source = None;
        self.file.downcast_mut()
    }

    /// `message` about the value at `field` (a dotted path) at its line and column in
    /// the file the scene was read from; `None` for a scene not read from a file.
    pub fn locate(&self, field: &str, message: String) -> Option<Located> {
        self.source.as_ref().map(|s| s.locate(field, message))
    }

    /// The file the scene was read from, as named when parsed.
    pub fn file(&self) -> Option<&Path> {
        self.source.as_ref().map(|s| s.file.as_path())
    }

    /// Build the simulation and renderer (see [`crate::Runner::with_limits`]).
    pub(crate) fn build(&self, assets: &Assets, limits: &Limits) -> Result<(BuiltBox, Estimate), BuildError> {
        self.entry.ops().build(&*self.file, assets, limits)
    }

    /// Read the scene's files and make every check its simulation and renderer would
    /// make, and estimate its cost, without building them (quick: what `validate`
    /// does). Refused like [`crate::Runner::with_limits`] when invalid or over `limits`.
    pub fn check(&self, assets: &Assets, limits: &Limits) -> Result<Report, BuildError> {
        let issues = self.validate();
        if !issues.is_empty() {
            return Err(BuildError::Invalid(issues));
        }
        self.entry.ops().check(&*self.file, assets, limits)
    }
}

impl Clone for Scene {
    fn clone(&self) -> Self {
        Self {
            entry: self.entry,
            file: self.entry.ops().clone_file(&*self.file),
            source: self.source.clone(),
        }
    }
}

impl PartialEq for Scene {
    /// Scenes are equal when their contents are (wherever they were read from).
    fn eq(&self, other: &Self) -> bool {
        self.entry == other.entry && self.entry.ops().eq_files(&*self.file, &*other.file)
    }
}

impl fmt::Debug for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.entry.ops().debug_file(&*self.file, f)
    }
}

/// Set `value` at a dotted path in a JSON object (see [`Scene::with_value`]).
pub fn set_path(root: &mut Value, path: &str, value: Value) -> Result<(), String> {
    let keys: Vec<&str> = path.split('.').collect();
    if keys.iter().any(|k| k.is_empty()) {
        return Err(format!("bad parameter path `{path}`"));
    }
    let (last, parents) = keys.split_last().ok_or_else(|| format!("bad parameter path `{path}`"))?;
    let mut at = root;
    for k in parents {
        at = at
            .get_mut(*k)
            .filter(|v| v.is_object())
            .ok_or_else(|| format!("no parameter `{path}` in this scene"))?;
    }
    let obj = at.as_object_mut().ok_or_else(|| format!("no parameter `{path}` in this scene"))?;
    if *last == "kind" {
        obj.clear();
        obj.insert("kind".into(), value);
        return Ok(());
    }
    // A key the scene's type does not know is refused when the JSON is read back.
    obj.insert((*last).to_string(), value);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn set_path_sets_leaves_and_resets_tagged_tables() {
        let mut v =
            json!({"render": {"background": {"kind": "checker", "light": [1, 1, 1]}, "intensity": 1}});
        set_path(&mut v, "render.intensity", json!(2)).unwrap();
        set_path(&mut v, "render.background.kind", json!("sky")).unwrap();
        assert_eq!(v, json!({"render": {"background": {"kind": "sky"}, "intensity": 2}}));
        assert!(set_path(&mut v, "render.nothing.x", json!(1)).is_err());
        assert!(set_path(&mut v, "render..x", json!(1)).is_err());
    }

    #[test]
    fn with_value_reads_back_through_the_types() {
        let scene = crate::shipped::shipped("flame-paper").unwrap().scene().unwrap();
        let seeded = scene.with_value("scene.seed", json!(77)).unwrap();
        assert_eq!(seeded.settings().seed, 77);
        assert!(scene.with_value("flame.nonsense", json!(1)).is_err(), "unknown keys are refused");
        assert!(scene.with_value("scene.seed", json!("x")).is_err());
    }
}
