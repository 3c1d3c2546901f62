//! [`Scene`]: a parsed scene file of any phenomenon, with typed access for code that
//! knows which one it holds.

use std::any::Any;
use std::fmt;
use std::path::Path;
use std::sync::Arc;

use phenomena_core::validate::{Issue, Issues};
use serde_json::Value;

use crate::assets::Assets;
use crate::output::Format;
use crate::parse::{Located, Source};
use crate::phenomenon::{Estimate, Phenomenon, View};
use crate::registry::{self, Entry};
use crate::runner::{BuildError, Limits, Report, Run};
use crate::settings::SceneSettings;

/// A scene of any phenomenon.
pub struct Scene {
    inner: Box<dyn AnyScene>,
    /// The file it was read from, to locate later problems (none once it is changed).
    source: Option<Arc<Source>>,
}

impl Scene {
    /// A scene holding `file`.
    pub fn new<P: Phenomenon>(file: P) -> Self {
        Self { inner: Box::new(file), source: None }
    }

    pub(crate) fn with_source(mut self, source: Source) -> Self {
        self.source = Some(Arc::new(source));
        self
    }

    /// Its phenomenon.
    pub fn phenomenon(&self) -> &'static dyn Entry {
        self.inner.entry()
    }

    /// The `[scene]` table.
    pub fn settings(&self) -> &SceneSettings {
        self.inner.settings()
    }

    /// The `[scene]` table, to change (command-line overrides: size, seed). Problems
    /// are still located in the file the scene was read from, whose other keys this
    /// does not move.
    pub fn settings_mut(&mut self) -> &mut SceneSettings {
        self.inner.settings_mut()
    }

    /// Every problem, with field paths from the file's root (`flame.sph.k`).
    pub fn validate(&self) -> Vec<Issue> {
        let mut i = Issues::default();
        self.inner.settings().validate(&mut i);
        self.inner.validate(&mut i);
        i.into_result().err().unwrap_or_default()
    }

    /// The view drawn.
    pub fn view(&self) -> &'static str {
        self.inner.view()
    }

    /// Draw `view`; a view the phenomenon cannot draw is refused with the ones it can.
    pub fn set_view(&mut self, view: &str) -> Result<(), String> {
        let p = self.phenomenon();
        if !p.views().iter().any(|v| v.name == view) {
            let names: Vec<&str> = p.views().iter().map(|v: &View| v.name).collect();
            return Err(format!("`{view}` is not a {} view: use {}", p.name(), names.join(" or ")));
        }
        // As for `settings_mut`, the file still locates problems with other keys.
        self.inner.set_view(view);
        Ok(())
    }

    /// Seconds of simulated time per frame.
    pub fn frame_time_s(&self) -> f64 {
        self.inner.frame_time_s()
    }

    /// Why a frame's image depends on the frames rendered before it, if it does
    /// ([`Phenomenon::render_memory`]).
    pub fn render_memory(&self) -> Option<&'static str> {
        self.inner.render_memory()
    }

    /// Whether `render` can write `format` for this scene; if not, the error names the
    /// formats it can.
    pub fn supports(&self, format: Format) -> Result<(), String> {
        let formats = self.phenomenon().formats();
        if formats.contains(&format) {
            return Ok(());
        }
        let names: Vec<&str> = formats.iter().map(|f| f.name()).collect();
        Err(format!(
            "{} scenes are not written as {}: use {}",
            self.phenomenon().name(),
            format.name(),
            names.join(", ")
        ))
    }

    /// Draw the phenomenon's light alone over black (for flipbooks); refused for a
    /// phenomenon that has no flipbook format.
    pub fn emission_only(&mut self) -> Result<(), String> {
        self.supports(Format::Flipbook)?;
        self.source = None;
        self.inner.emission_only();
        Ok(())
    }

    /// The scene as JSON (the form a front end edits; [`crate::registry::Entry::scene_from_json`] reads it).
    pub fn to_json(&self) -> Value {
        self.inner.to_json()
    }

    /// The scene as a TOML file that reads back to the same scene.
    pub fn to_toml(&self) -> Result<String, String> {
        self.inner.to_toml()
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
        self.inner.as_any().downcast_ref()
    }

    /// The phenomenon's file struct, to change, when it is `P`.
    pub fn get_mut<P: Phenomenon>(&mut self) -> Option<&mut P> {
        self.source = None;
        self.inner.as_any_mut().downcast_mut()
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

    pub(crate) fn build(
        &self,
        assets: &Assets,
        limits: &Limits,
    ) -> Result<(Box<dyn Run>, Estimate), BuildError> {
        self.inner.build(assets, limits)
    }

    /// Read the scene's files and make every check its simulation and renderer would
    /// make, and estimate its cost, without building them (quick: what `validate`
    /// does). Refused like [`crate::Runner::with_limits`] when invalid or over `limits`.
    pub fn check(&self, assets: &Assets, limits: &Limits) -> Result<Report, BuildError> {
        let issues = self.validate();
        if !issues.is_empty() {
            return Err(BuildError::Invalid(issues));
        }
        self.inner.check(assets, limits)
    }
}

impl Clone for Scene {
    fn clone(&self) -> Self {
        Self { inner: self.inner.clone_box(), source: self.source.clone() }
    }
}

impl PartialEq for Scene {
    /// Scenes are equal when their contents are (wherever they were read from).
    fn eq(&self, other: &Self) -> bool {
        self.inner.eq_dyn(&*other.inner)
    }
}

impl fmt::Debug for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.inner.fmt(f)
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

/// A phenomenon's file struct without its type.
trait AnyScene: Send + Sync + fmt::Debug {
    fn entry(&self) -> &'static dyn Entry;
    fn settings(&self) -> &SceneSettings;
    fn settings_mut(&mut self) -> &mut SceneSettings;
    fn validate(&self, issues: &mut Issues);
    fn view(&self) -> &'static str;
    fn set_view(&mut self, view: &str);
    fn to_json(&self) -> Value;
    fn frame_time_s(&self) -> f64;
    fn emission_only(&mut self);
    fn render_memory(&self) -> Option<&'static str>;
    fn to_toml(&self) -> Result<String, String>;
    fn build(&self, assets: &Assets, limits: &Limits) -> Result<(Box<dyn Run>, Estimate), BuildError>;
    fn check(&self, assets: &Assets, limits: &Limits) -> Result<Report, BuildError>;
    fn clone_box(&self) -> Box<dyn AnyScene>;
    fn eq_dyn(&self, other: &dyn AnyScene) -> bool;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<P: Phenomenon> AnyScene for P {
    fn entry(&self) -> &'static dyn Entry {
        // Every implementation of `Phenomenon` is listed in the registry (a test checks
        // each module's name is there).
        registry::phenomenon(P::NAME).unwrap_or(registry::PHENOMENA[0])
    }

    fn settings(&self) -> &SceneSettings {
        Phenomenon::settings(self)
    }

    fn settings_mut(&mut self) -> &mut SceneSettings {
        Phenomenon::settings_mut(self)
    }

    fn validate(&self, issues: &mut Issues) {
        Phenomenon::validate(self, issues)
    }

    fn view(&self) -> &'static str {
        Phenomenon::view(self)
    }

    fn set_view(&mut self, view: &str) {
        Phenomenon::set_view(self, view)
    }

    fn to_json(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }

    fn to_toml(&self) -> Result<String, String> {
        toml::to_string(self).map_err(|e| e.to_string())
    }

    fn frame_time_s(&self) -> f64 {
        Phenomenon::frame_time_s(self)
    }

    fn emission_only(&mut self) {
        Phenomenon::emission_only(self)
    }

    fn render_memory(&self) -> Option<&'static str> {
        Phenomenon::render_memory(self)
    }

    fn build(&self, assets: &Assets, limits: &Limits) -> Result<(Box<dyn Run>, Estimate), BuildError> {
        crate::runner::live(self, assets, limits)
    }

    fn check(&self, assets: &Assets, limits: &Limits) -> Result<Report, BuildError> {
        crate::runner::check(self, assets, limits)
    }

    fn clone_box(&self) -> Box<dyn AnyScene> {
        Box::new(self.clone())
    }

    fn eq_dyn(&self, other: &dyn AnyScene) -> bool {
        other.as_any().downcast_ref::<P>().is_some_and(|o| o == self)
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
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
        let scene = crate::registry::shipped("flame-paper").unwrap().scene().unwrap();
        let seeded = scene.with_value("scene.seed", json!(77)).unwrap();
        assert_eq!(seeded.settings().seed, 77);
        assert!(scene.with_value("flame.nonsense", json!(1)).is_err(), "unknown keys are refused");
        assert!(scene.with_value("scene.seed", json!("x")).is_err());
    }
}
