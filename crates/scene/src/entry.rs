//! A phenomenon without its types: [`Entry`], what the registry lists, and the one
//! erased trait behind it. Everything above this module (scenes, the runner, the output
//! formats, the CLI and the studio) reaches a phenomenon's file struct, simulation and
//! renderer only through an [`Entry`], so a new [`Phenomenon`] hook is one method here
//! and its one implementation below.
//!
//! A scene's file struct and a built simulation travel as `Box<dyn Any>` beside their
//! entry; the entry that made a box is the only one that opens it (a [`crate::Scene`] and
//! a [`crate::Runner`] keep the pair together), so every downcast below succeeds.

use std::any::Any;
use std::fmt;
use std::marker::PhantomData;

use phenomena_core::clock::SharedClock;
use phenomena_core::image::Frame;
use phenomena_core::phenomenon::{Layer, Renderer, Simulation};
use phenomena_core::validate::Issues;
use serde_json::Value;

use crate::assets::Assets;
use crate::budget::{Estimate, Limits, Report};
use crate::checkpoint::{self, CheckpointError, Header};
use crate::error::{BuildError, SinkError};
use crate::phenomenon::{
    Built, Capability, ExportKind, Exported, MotionVectors, Phenomenon, Scratch, Steer, View, VolumeOptions,
    VolumeOut,
};
use crate::settings::SceneSettings;
use crate::source::{Unread, deserialize_all};

/// A scene file's struct of some phenomenon.
pub(crate) type FileBox = Box<dyn Any + Send + Sync>;
/// A built simulation and renderer of some phenomenon.
pub(crate) type BuiltBox = Box<dyn Any + Send>;

/// A phenomenon as tools see it: its name, views, exports and what it can give, its
/// starter scene; and (inside the crate) every operation on its scenes and simulations.
#[derive(Clone, Copy)]
pub struct Entry(&'static dyn Dispatch);

impl Entry {
    /// The entry of phenomenon `P`.
    pub const fn of<P: Phenomenon>() -> Self {
        Entry(&Registered::<P>(PhantomData))
    }

    /// Its table name (`flame`).
    pub fn name(self) -> &'static str {
        self.0.name()
    }

    /// One line on what it is.
    pub fn about(self) -> &'static str {
        self.0.about()
    }

    /// Its views; the first is the default.
    pub fn views(self) -> &'static [View] {
        self.0.views()
    }

    /// Its data exports.
    pub fn exports(self) -> &'static [ExportKind] {
        self.0.exports()
    }

    /// Whether it can give `what` (some output formats need it).
    pub fn can(self, what: Capability) -> bool {
        self.0.capabilities().contains(&what)
    }

    /// Whether it is the composition of the others (a shot of several phenomena).
    pub fn composite(self) -> bool {
        self.0.composite()
    }

    /// Its commented starter scene.
    pub fn starter(self) -> &'static str {
        self.0.starter()
    }

    /// A scene holding every default.
    pub fn default_scene(self) -> crate::Scene {
        crate::Scene::from_parts(self, self.0.default_file(), None)
    }

    /// A scene from its JSON form (what [`crate::Scene::to_json`] gives; not validated).
    pub fn scene_from_json(self, value: Value) -> Result<crate::Scene, String> {
        Ok(crate::Scene::from_parts(self, self.0.file_from_json(value)?, None))
    }

    /// The operations on its scenes and simulations.
    pub(crate) fn ops(self) -> &'static dyn Dispatch {
        self.0
    }
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
    }
}

impl Eq for Entry {}

impl fmt::Debug for Entry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Entry({})", self.name())
    }
}

/// Every operation on a phenomenon's scenes (`file`: its file struct) and built
/// simulations (`built`), without their types: the one erased trait.
pub(crate) trait Dispatch: Sync {
    // What the phenomenon is.
    fn name(&self) -> &'static str;
    fn about(&self) -> &'static str;
    fn views(&self) -> &'static [View];
    fn exports(&self) -> &'static [ExportKind];
    fn capabilities(&self) -> &'static [Capability];
    fn starter(&self) -> &'static str;
    fn composite(&self) -> bool;

    // Its scene files.
    fn default_file(&self) -> FileBox;
    fn parse_file(&self, text: &str) -> Result<FileBox, Unread<FileBox>>;
    fn file_from_json(&self, value: Value) -> Result<FileBox, String>;
    fn clone_file(&self, file: &dyn Any) -> FileBox;
    fn eq_files(&self, a: &dyn Any, b: &dyn Any) -> bool;
    fn debug_file(&self, file: &dyn Any, f: &mut fmt::Formatter<'_>) -> fmt::Result;
    fn settings<'a>(&self, file: &'a dyn Any) -> &'a SceneSettings;
    fn settings_mut<'a>(&self, file: &'a mut dyn Any) -> &'a mut SceneSettings;
    fn validate(&self, file: &dyn Any, issues: &mut Issues);
    fn view(&self, file: &dyn Any) -> &'static str;
    fn set_view(&self, file: &mut dyn Any, view: &str);
    fn to_json(&self, file: &dyn Any) -> Value;
    fn to_toml(&self, file: &dyn Any) -> Result<String, String>;
    fn frame_time_s(&self, file: &dyn Any) -> f64;
    fn emission_only(&self, file: &mut dyn Any);
    fn render_memory(&self, file: &dyn Any) -> Option<&'static str>;
    fn check(&self, file: &dyn Any, assets: &Assets, limits: &Limits) -> Result<Report, BuildError>;
    fn build(
        &self,
        file: &dyn Any,
        assets: &Assets,
        limits: &Limits,
    ) -> Result<(BuiltBox, Estimate), BuildError>;

    // Its built simulations.
    fn step(&self, built: &mut dyn Any) -> Result<Value, String>;
    /// Render; the time of the next frame's step when it was taken beside the render
    /// (timed on `clock`).
    fn render(&self, built: &mut dyn Any, preview: Option<u32>, clock: &SharedClock) -> Option<f64>;
    fn frame<'a>(&self, built: &'a dyn Any) -> &'a Frame;
    fn layers<'a>(&self, built: &'a dyn Any) -> Vec<Layer<'a>>;
    fn render_detail(&self, built: &dyn Any) -> Option<Value>;
    fn set_clock(&self, built: &mut dyn Any, clock: &SharedClock);
    fn export(&self, built: &dyn Any, name: &str, format: &str) -> Result<Exported, String>;
    fn steer(&self, built: &mut dyn Any, path: &str, value: &Value) -> Steer;
    fn warnings<'a>(&self, built: &'a dyn Any) -> &'a [String];
    fn frames_done(&self, built: &dyn Any) -> u64;
    fn header(&self, built: &dyn Any) -> Header;
    fn restore(&self, built: &mut dyn Any, payload: &[u8]) -> Result<(), CheckpointError>;
    fn checkpoint(&self, built: &dyn Any) -> Result<Vec<u8>, SinkError>;
    fn volume(
        &self,
        built: &dyn Any,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut VolumeOut<'_>,
    ) -> Result<Value, SinkError>;
    fn volume_bytes(&self, built: &dyn Any, options: &VolumeOptions) -> Result<u64, SinkError>;
    fn points(&self, built: &dyn Any) -> Result<Vec<u8>, SinkError>;
    fn motion(&self, built: &dyn Any) -> Result<MotionVectors, SinkError>;
}

/// Phenomenon `P`'s [`Dispatch`].
struct Registered<P>(PhantomData<fn() -> P>);

/// A built phenomenon: its simulation and renderer, and what its checkpoints carry.
struct Live<P: Phenomenon> {
    built: Built<P>,
    /// The scene's checkpoint identity ([`checkpoint::identity`]).
    identity: u64,
    seed: u64,
    /// A copy of the simulation the next frame is stepped on while this one renders
    /// ([`Phenomenon::sync_spare`]).
    spare: Option<P::Sim>,
    /// The spare's step, when the spare holds the next frame: the next `step` takes it
    /// (swapping the spare in) instead of stepping. Anything else that changes the
    /// simulation (steering, a checkpoint, a clock) drops it.
    ahead: Option<Result<Value, String>>,
}

/// Step `sim` one frame, its counters as JSON.
fn step_value<S: Simulation>(sim: &mut S) -> Result<Value, String> {
    let stats = sim.step().map_err(|e| e.to_string())?;
    serde_json::to_value(stats).map_err(|e| e.to_string())
}

/// `P`'s file struct in `file` (the entry that made the box opens it).
fn file<P: Phenomenon>(file: &dyn Any) -> &P {
    match file.downcast_ref::<P>() {
        Some(p) => p,
        None => unreachable!("a {} entry was given another phenomenon's scene", P::NAME),
    }
}

fn file_mut<P: Phenomenon>(file: &mut dyn Any) -> &mut P {
    match file.downcast_mut::<P>() {
        Some(p) => p,
        None => unreachable!("a {} entry was given another phenomenon's scene", P::NAME),
    }
}

fn live<P: Phenomenon>(built: &dyn Any) -> &Live<P> {
    match built.downcast_ref::<Live<P>>() {
        Some(l) => l,
        None => unreachable!("a {} entry was given another phenomenon's simulation", P::NAME),
    }
}

fn live_mut<P: Phenomenon>(built: &mut dyn Any) -> &mut Live<P> {
    match built.downcast_mut::<Live<P>>() {
        Some(l) => l,
        None => unreachable!("a {} entry was given another phenomenon's simulation", P::NAME),
    }
}

/// The phenomenon's estimate plus writing a frame: the frame interleaved as f32 and as
/// 8-bit sRGB for PNG (EXR copies the planes, the same order of size), and the spare it
/// steps ahead on ([`Phenomenon::spare_bytes`]; charged also to a run that renders no
/// frame, which makes none).
fn estimate<P: Phenomenon>(scene: &P, loaded: &P::Loaded) -> Estimate {
    let (w, h) = scene.settings().size();
    let estimate = scene.estimate(loaded).with("writing a frame", (w as u64) * (h as u64) * 15);
    match scene.spare_bytes(loaded) {
        0 => estimate,
        spare => estimate.with("a spare of the simulation, stepped while a frame renders", spare),
    }
}

impl<P: Phenomenon> Dispatch for Registered<P> {
    fn name(&self) -> &'static str {
        P::NAME
    }

    fn about(&self) -> &'static str {
        P::ABOUT
    }

    fn views(&self) -> &'static [View] {
        P::VIEWS
    }

    fn exports(&self) -> &'static [ExportKind] {
        P::EXPORTS
    }

    fn capabilities(&self) -> &'static [Capability] {
        P::CAN
    }

    fn starter(&self) -> &'static str {
        P::STARTER
    }

    fn composite(&self) -> bool {
        P::COMPOSITE
    }

    fn default_file(&self) -> FileBox {
        Box::new(P::default())
    }

    fn parse_file(&self, text: &str) -> Result<FileBox, Unread<FileBox>> {
        match deserialize_all::<P>(text) {
            Ok(p) => Ok(Box::new(p)),
            Err((errors, rest)) => Err((errors, rest.map(|p| Box::new(p) as FileBox))),
        }
    }

    fn file_from_json(&self, value: Value) -> Result<FileBox, String> {
        serde_json::from_value::<P>(value).map(|p| Box::new(p) as FileBox).map_err(|e| e.to_string())
    }

    fn clone_file(&self, f: &dyn Any) -> FileBox {
        Box::new(file::<P>(f).clone())
    }

    fn eq_files(&self, a: &dyn Any, b: &dyn Any) -> bool {
        b.downcast_ref::<P>().is_some_and(|b| b == file::<P>(a))
    }

    fn debug_file(&self, f: &dyn Any, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(file::<P>(f), out)
    }

    fn settings<'a>(&self, f: &'a dyn Any) -> &'a SceneSettings {
        file::<P>(f).settings()
    }

    fn settings_mut<'a>(&self, f: &'a mut dyn Any) -> &'a mut SceneSettings {
        file_mut::<P>(f).settings_mut()
    }

    fn validate(&self, f: &dyn Any, issues: &mut Issues) {
        file::<P>(f).validate(issues)
    }

    fn view(&self, f: &dyn Any) -> &'static str {
        file::<P>(f).view()
    }

    fn set_view(&self, f: &mut dyn Any, view: &str) {
        file_mut::<P>(f).set_view(view)
    }

    fn to_json(&self, f: &dyn Any) -> Value {
        serde_json::to_value(file::<P>(f)).unwrap_or(Value::Null)
    }

    fn to_toml(&self, f: &dyn Any) -> Result<String, String> {
        toml::to_string(file::<P>(f)).map_err(|e| e.to_string())
    }

    fn frame_time_s(&self, f: &dyn Any) -> f64 {
        file::<P>(f).frame_time_s()
    }

    fn emission_only(&self, f: &mut dyn Any) {
        file_mut::<P>(f).emission_only()
    }

    fn render_memory(&self, f: &dyn Any) -> Option<&'static str> {
        file::<P>(f).render_memory()
    }

    /// Read the scene's files and run its checks without building anything.
    fn check(&self, f: &dyn Any, assets: &Assets, limits: &Limits) -> Result<Report, BuildError> {
        let scene = file::<P>(f);
        let loaded = scene.load(assets)?;
        let warnings = scene.check(&loaded)?;
        let estimate = estimate(scene, &loaded).within(limits)?;
        Ok(Report { warnings, estimate })
    }

    /// Read the scene's files, make the checks `validate` makes (so a render is refused
    /// with the same located problems), refuse it when its estimate is over `limits`,
    /// build.
    fn build(
        &self,
        f: &dyn Any,
        assets: &Assets,
        limits: &Limits,
    ) -> Result<(BuiltBox, Estimate), BuildError> {
        let scene = file::<P>(f);
        let loaded = scene.load(assets)?;
        scene.check(&loaded)?;
        let estimate = estimate(scene, &loaded).within(limits)?;
        let identity = checkpoint::identity(P::NAME, &scene.simulation_tables(), P::files_identity(&loaded));
        let seed = scene.settings().seed;
        let live = Live::<P> { built: scene.build(loaded)?, identity, seed, spare: None, ahead: None };
        Ok((Box::new(live), estimate))
    }

    /// The step taken ahead while the last frame rendered, if there is one (the spare,
    /// which took it, swapped in when it went well), else a step now.
    fn step(&self, b: &mut dyn Any) -> Result<Value, String> {
        let live = live_mut::<P>(b);
        match (live.ahead.take(), live.spare.as_mut()) {
            (Some(Ok(counters)), Some(spare)) => {
                std::mem::swap(&mut live.built.sim, spare);
                Ok(counters)
            }
            (Some(Err(e)), _) => Err(e),
            _ => step_value(&mut live.built.sim),
        }
    }

    /// Render the current state; where the phenomenon steps ahead
    /// ([`Phenomenon::sync_spare`]) and the next frame is not stepped yet, step it on
    /// the spare at the same time (`rayon::join`: the step's one-thread parts run while
    /// the render's parallel parts take the other threads). The simulation itself is
    /// left as it was, so what is read after the render (a checkpoint, a volume) is
    /// this frame's. Gives the time of the step taken beside the render.
    fn render(&self, b: &mut dyn Any, preview: Option<u32>, clock: &SharedClock) -> Option<f64> {
        let live = live_mut::<P>(b);
        P::before_render(&mut live.built, preview);
        let Live { built: Built { sim, renderer, .. }, spare, ahead, .. } = live;
        if ahead.is_none()
            && P::sync_spare(sim, spare)
            && let Some(next) = spare.as_mut()
        {
            let step = || {
                let t = clock.stopwatch();
                (step_value(next), t.ms())
            };
            let ((stepped, ms), _) = rayon::join(step, || renderer.render(sim));
            *ahead = Some(stepped);
            Some(ms)
        } else {
            renderer.render(sim);
            None
        }
    }

    fn frame<'a>(&self, b: &'a dyn Any) -> &'a Frame {
        live::<P>(b).built.renderer.frame()
    }

    fn layers<'a>(&self, b: &'a dyn Any) -> Vec<Layer<'a>> {
        live::<P>(b).built.renderer.layers()
    }

    fn render_detail(&self, b: &dyn Any) -> Option<Value> {
        P::render_detail(&live::<P>(b).built)
    }

    fn set_clock(&self, b: &mut dyn Any, clock: &SharedClock) {
        let live = live_mut::<P>(b);
        live.ahead = None;
        P::set_clock(&mut live.built, clock)
    }

    fn export(&self, b: &dyn Any, name: &str, format: &str) -> Result<Exported, String> {
        P::export(&live::<P>(b).built, name, format)
    }

    fn steer(&self, b: &mut dyn Any, path: &str, value: &Value) -> Steer {
        let live = live_mut::<P>(b);
        live.ahead = None;
        P::steer(&mut live.built, path, value)
    }

    fn warnings<'a>(&self, b: &'a dyn Any) -> &'a [String] {
        &live::<P>(b).built.warnings
    }

    fn frames_done(&self, b: &dyn Any) -> u64 {
        live::<P>(b).built.sim.frames_done()
    }

    fn header(&self, b: &dyn Any) -> Header {
        let l = live::<P>(b);
        Header {
            phenomenon: P::NAME.to_string(),
            identity: l.identity,
            seed: l.seed,
            frames_done: l.built.sim.frames_done(),
        }
    }

    fn restore(&self, b: &mut dyn Any, payload: &[u8]) -> Result<(), CheckpointError> {
        let state = checkpoint::decode_state(payload)?;
        let live = live_mut::<P>(b);
        live.ahead = None;
        live.built.sim.restore(state).map_err(|e| CheckpointError::State(e.to_string()))
    }

    fn checkpoint(&self, b: &dyn Any) -> Result<Vec<u8>, SinkError> {
        checkpoint::encode(&self.header(b), &live::<P>(b).built.sim.state())
            .map_err(|e| SinkError(e.to_string()))
    }

    fn volume(
        &self,
        b: &dyn Any,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut VolumeOut<'_>,
    ) -> Result<Value, SinkError> {
        P::volume(&live::<P>(b).built, options, scratch, out).map_err(SinkError)
    }

    fn volume_bytes(&self, b: &dyn Any, options: &VolumeOptions) -> Result<u64, SinkError> {
        P::volume_bytes(&live::<P>(b).built, options).map_err(SinkError)
    }

    fn points(&self, b: &dyn Any) -> Result<Vec<u8>, SinkError> {
        let mut cache = P::points(&live::<P>(b).built).map_err(SinkError)?;
        cache.comments.push(format!("phenomena {} particles after {} frames", P::NAME, self.frames_done(b)));
        cache.to_ply().map_err(SinkError)
    }

    fn motion(&self, b: &dyn Any) -> Result<MotionVectors, SinkError> {
        P::motion(&live::<P>(b).built).map_err(SinkError)
    }
}
