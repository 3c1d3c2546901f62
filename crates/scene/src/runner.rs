//! The one render loop: build a scene's simulation and renderer ([`Runner::new`]), step
//! it frame by frame and hand the frames wanted to a [`FrameSink`] (PNG or EXR files,
//! the studio's preview, ...), reporting each frame to an [`Observer`] (progress,
//! statistics, cancellation). `render`, `demo`, `export`, the studio's preview and its
//! final renders all run through it.

use std::ops::{ControlFlow, Range};

use phenomena_core::clock::SharedClock;
use phenomena_core::image::Frame;
use phenomena_core::phenomenon::RenderError;
use phenomena_core::phenomenon::{Layer, Renderer, Simulation};
use phenomena_core::tonemap::Exposure;
use phenomena_core::validate::{InvalidConfig, Issue};
use serde::Serialize;
use serde_json::Value;

use crate::assets::{AssetError, Assets};
use crate::checkpoint::{self, CheckpointError, Header};
use crate::phenomenon::{Built, Estimate, Exported, Phenomenon, Scratch, Steer, VolumeOptions};
use crate::scene::Scene;

/// Why a scene's simulation or renderer could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The scene is not valid (a scene changed after it was read, say).
    #[error("the scene is not valid: {}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    Invalid(Vec<Issue>),
    /// A file could not be read.
    #[error(transparent)]
    Asset(#[from] AssetError),
    /// A file was read but cannot be used (a mesh that does not parse, say).
    #[error("{key}: {message}")]
    Unusable {
        /// The scene key that names the file.
        key: String,
        /// What is wrong with it.
        message: String,
    },
    /// The simulation or renderer refused the scene.
    #[error("{0}")]
    Refused(String),
    /// The scene would need more memory than the budget allows.
    #[error(
        "the scene needs about {} of memory ({}), more than the budget of {}",
        gib(.estimate.memory_bytes),
        .estimate.work,
        gib(*.limit_bytes)
    )]
    OverBudget {
        /// What it would need.
        estimate: Box<Estimate>,
        /// The budget, bytes.
        limit_bytes: u64,
    },
}

/// Bytes as GiB, for messages.
pub fn gib(bytes: u64) -> String {
    format!("{:.2} GiB", bytes as f64 / f64::from(1u32 << 30))
}

/// How much a run may take. The CLI's default is three quarters of the machine's
/// memory; a library caller sets its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Most memory the scene's estimate may reach, bytes.
    pub memory_bytes: u64,
}

impl Limits {
    /// No limit.
    pub const NONE: Limits = Limits { memory_bytes: u64::MAX };
}

/// What checking a scene found: warnings and the estimate of its cost.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Warnings, each a sentence.
    pub warnings: Vec<String>,
    /// Memory and work.
    pub estimate: Estimate,
}

impl BuildError {
    /// The scene key the problem is at, if it is at one.
    pub fn key(&self) -> Option<&str> {
        match self {
            BuildError::Asset(e) => Some(&e.key),
            BuildError::Unusable { key, .. } => Some(key),
            BuildError::Invalid(issues) => issues.first().map(|i| i.field.as_str()),
            BuildError::Refused(_) | BuildError::OverBudget { .. } => None,
        }
    }

    /// A simulation's or renderer's refusal.
    pub fn refused(e: impl std::fmt::Display) -> Self {
        BuildError::Refused(e.to_string())
    }

    /// A constructor's invalid configuration, its fields put under `table` (the key the
    /// configuration sits at in the scene file, e.g. `sparkle` or `render.sky`).
    pub fn invalid(table: &str, config: InvalidConfig) -> Self {
        BuildError::Invalid(config.prefixed(table).issues)
    }

    /// A renderer's refusal: its invalid settings under `table`, anything else as is.
    pub fn render(table: &str, e: RenderError) -> Self {
        match e {
            RenderError::Invalid(c) => Self::invalid(table, c),
            other => Self::refused(other),
        }
    }
}

/// Why a run stopped early.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The simulation failed.
    #[error("the simulation failed at frame {frame}: {message}")]
    Step {
        /// The frame being made.
        frame: u32,
        /// Why.
        message: String,
    },
    /// The sink could not take a frame.
    #[error("frame {frame}: {error}")]
    Sink {
        /// The frame.
        frame: u32,
        /// Why (in the message: not also a `source`, which would print it twice).
        error: SinkError,
    },
    /// The observer asked to stop.
    #[error("stopped after {frames} frame(s)")]
    Cancelled {
        /// Frames finished.
        frames: u32,
    },
    /// The frames asked for start before the simulation's current frame.
    #[error("frame {asked} is already past: the simulation is at frame {at}")]
    Past {
        /// The first frame asked for.
        asked: u32,
        /// Frames already simulated.
        at: u32,
    },
}

/// Why a sink could not take a frame.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct SinkError(pub String);

/// What one frame did: timings (0 unless the runner has a clock), the phenomenon's
/// counters, and what happened to its image. One JSON object per frame in `--stats`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameRecord {
    /// The frame (the state after `frame + 1` steps).
    pub frame: u32,
    /// Time of the step, ms.
    pub step_ms: f64,
    /// Time of the render, ms (`None`: not rendered).
    pub render_ms: Option<f64>,
    /// The renderer's own breakdown of `render_ms`, where it has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub render_detail: Option<Value>,
    /// Time the sink took, ms.
    pub write_ms: Option<f64>,
    /// The sink already had this frame (`--resume`).
    pub skipped: bool,
    /// The phenomenon's counters (particles, passes, ...).
    #[serde(flatten)]
    pub counters: Value,
}

/// A frame handed to a sink: its image (when a sink asked for one) and the
/// simulation's state, for sinks that write data rather than pictures.
pub struct Output<'a> {
    /// Its frame number.
    pub index: u32,
    /// Linear (scene-referred) RGB: the render of this frame when a sink taking it
    /// [`FrameSink::needs_image`], else the last frame rendered (or black).
    pub frame: &'a Frame,
    /// Extra images (EXR layers), as `frame`.
    pub layers: &'a [Layer<'a>],
    /// Whether `frame` and `layers` are this frame's render.
    pub rendered: bool,
    /// The scene's exposure and tone map (for display encodings).
    pub exposure: Exposure,
    /// The frame's record so far (step and render timings, counters).
    pub record: &'a FrameRecord,
    /// The simulation's data at this frame (checkpoints, volumes, point caches).
    pub data: &'a dyn Products,
}

/// What a simulation's state can be turned into, besides images.
pub trait Products {
    /// A checkpoint of the whole state ([`crate::checkpoint`]'s format).
    fn checkpoint(&self) -> Result<Vec<u8>, SinkError>;
    /// The state as an OpenVDB file's bytes, into `out` (cleared first), with buffers
    /// kept in `scratch` from frame to frame; returns the file's manifest
    /// ([`crate::phenomenon::encode_volume`]).
    fn volume(
        &self,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut Vec<u8>,
    ) -> Result<Value, SinkError>;
    /// The particles as a binary PLY file's bytes.
    fn points(&self) -> Result<Vec<u8>, SinkError>;
    /// Bytes a volume at `options` takes ([`Phenomenon::volume_bytes`]).
    fn volume_bytes(&self, options: &VolumeOptions) -> Result<u64, SinkError>;
}

/// Where rendered frames go.
pub trait FrameSink {
    /// Whether frame `index` is to be rendered and written (`false`: the sink has it
    /// already, e.g. a finished file when resuming, or does not take it).
    fn wants(&mut self, _index: u32) -> bool {
        true
    }

    /// Whether the frames it takes must be rendered (a sink of simulation data, such
    /// as checkpoints, does not need the image).
    fn needs_image(&self) -> bool {
        true
    }

    /// Take one frame.
    fn write(&mut self, output: &Output<'_>) -> Result<(), SinkError>;

    /// The run is over (every frame it asked for was given): write what is written
    /// once (a flipbook's atlas). Not called when the run stops early.
    fn finish(&mut self) -> Result<(), SinkError> {
        Ok(())
    }
}

/// A sink that takes nothing: the frames are simulated, not rendered.
pub struct Simulate;

impl FrameSink for Simulate {
    fn wants(&mut self, _index: u32) -> bool {
        false
    }

    fn write(&mut self, _output: &Output<'_>) -> Result<(), SinkError> {
        Ok(())
    }
}

/// A sink that passes on only the frames of `frames` (the rest are simulated only).
pub struct Only<'a> {
    /// The frames passed on.
    pub frames: Range<u32>,
    /// Where they go.
    pub sink: &'a mut dyn FrameSink,
}

impl FrameSink for Only<'_> {
    fn wants(&mut self, index: u32) -> bool {
        self.frames.contains(&index) && self.sink.wants(index)
    }

    fn needs_image(&self) -> bool {
        self.sink.needs_image()
    }

    fn write(&mut self, output: &Output<'_>) -> Result<(), SinkError> {
        self.sink.write(output)
    }

    fn finish(&mut self) -> Result<(), SinkError> {
        self.sink.finish()
    }
}

/// Several sinks fed by one run: each frame is rendered once, when any sink that
/// wants it needs the image, and given to every sink that wants it, in order.
pub struct Tee<'a> {
    sinks: Vec<&'a mut dyn FrameSink>,
    wanted: Vec<bool>,
}

impl<'a> Tee<'a> {
    /// The sinks, written in this order.
    pub fn new(sinks: Vec<&'a mut dyn FrameSink>) -> Self {
        let wanted = vec![false; sinks.len()];
        Self { sinks, wanted }
    }
}

impl FrameSink for Tee<'_> {
    fn wants(&mut self, index: u32) -> bool {
        for (w, s) in self.wanted.iter_mut().zip(&mut self.sinks) {
            *w = s.wants(index);
        }
        self.wanted.iter().any(|&w| w)
    }

    fn needs_image(&self) -> bool {
        self.sinks.iter().zip(&self.wanted).any(|(s, &w)| w && s.needs_image())
    }

    fn write(&mut self, output: &Output<'_>) -> Result<(), SinkError> {
        for (s, &w) in self.sinks.iter_mut().zip(&self.wanted) {
            if w {
                s.write(output)?;
            }
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<(), SinkError> {
        self.sinks.iter_mut().try_for_each(|s| s.finish())
    }
}

/// Told about every frame as it finishes; may stop the run.
pub trait Observer {
    /// Frame `record.frame` is done (stepped, and rendered if it was wanted).
    fn frame(&mut self, record: &FrameRecord) -> ControlFlow<()>;
}

impl Observer for () {
    fn frame(&mut self, _record: &FrameRecord) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
}

/// A phenomenon's simulation and renderer, stepped together.
pub struct Runner {
    run: Box<dyn Run>,
    estimate: Estimate,
    clock: SharedClock,
    exposure: Exposure,
    preview: bool,
    /// Why a frame's image depends on earlier renders ([`Scene::render_memory`]).
    render_memory: Option<&'static str>,
}

impl Runner {
    /// Build the simulation and renderer of `scene` (validated first), reading its
    /// files through `assets`, with no memory limit.
    pub fn new(scene: &Scene, assets: &Assets) -> Result<Self, BuildError> {
        Self::with_limits(scene, assets, &Limits::NONE)
    }

    /// As [`Runner::new`], refusing a scene whose estimated memory is over `limits`
    /// before building anything.
    pub fn with_limits(scene: &Scene, assets: &Assets, limits: &Limits) -> Result<Self, BuildError> {
        let issues = scene.validate();
        if !issues.is_empty() {
            return Err(BuildError::Invalid(issues));
        }
        let (run, estimate) = scene.build(assets, limits)?;
        Ok(Self {
            run,
            estimate,
            clock: SharedClock::default(),
            exposure: scene.settings().exposure(),
            preview: false,
            render_memory: scene.render_memory(),
        })
    }

    /// Time steps, renders and writes (and the phenomena's own breakdowns) with
    /// `clock`; without one every timing is 0.
    pub fn set_clock(&mut self, clock: SharedClock) {
        self.run.set_clock(&clock);
        self.clock = clock;
    }

    /// Render fast previews (the studio) instead of final frames, where the phenomenon
    /// has a preview mode.
    pub fn set_preview(&mut self, preview: bool) {
        self.preview = preview;
    }

    /// The estimate of the scene's memory and work the runner was built under.
    pub fn estimate(&self) -> &Estimate {
        &self.estimate
    }

    /// Add what writing the frames takes (`parts`: what, bytes; a flipbook's atlas, a
    /// volume's grids) to the estimate, refused like [`Runner::with_limits`] when the
    /// whole is over `limits`: checked before the first frame.
    pub fn admit(&mut self, parts: Vec<(String, u64)>, limits: &Limits) -> Result<(), BuildError> {
        let mut estimate = self.estimate.clone();
        for (what, bytes) in parts {
            estimate.memory_bytes = estimate.memory_bytes.saturating_add(bytes);
            estimate.parts.push((what, bytes));
        }
        self.estimate = within(estimate, limits)?;
        Ok(())
    }

    /// Bytes a volume of the current state at `options` takes (an upper bound that
    /// allows for the state's growth), checking the voxel size.
    pub fn volume_bytes(&self, options: &VolumeOptions) -> Result<u64, SinkError> {
        self.run.as_products().volume_bytes(options)
    }

    /// Warnings found while building (each a sentence).
    pub fn warnings(&self) -> &[String] {
        self.run.warnings()
    }

    /// Frames simulated so far.
    pub fn frames_done(&self) -> u32 {
        u32::try_from(self.run.frames_done()).unwrap_or(u32::MAX)
    }

    /// The frame of the last render.
    pub fn frame(&self) -> &Frame {
        self.run.frame()
    }

    /// Simulate one frame.
    pub fn step(&mut self) -> Result<FrameRecord, RunError> {
        let frame = self.frames_done();
        let t = self.clock.stopwatch();
        let counters = self.run.step().map_err(|message| RunError::Step { frame, message })?;
        Ok(FrameRecord { frame, step_ms: t.ms(), counters, ..FrameRecord::default() })
    }

    /// Why this scene's frames depend on the frames rendered before them, if they do
    /// ([`Scene::render_memory`]): every frame simulated is then rendered, and
    /// [`Runner::restore`] refuses checkpoints.
    pub fn render_memory(&self) -> Option<&'static str> {
        self.render_memory
    }

    /// Render the current state, completing `record`'s timings.
    fn render(&mut self, record: &mut FrameRecord) {
        let t = self.clock.stopwatch();
        // A preview's subset turns with the frames simulated (0 before the first step).
        let done = self.frames_done();
        self.run.render(self.preview.then_some(done));
        record.render_ms = Some(t.ms());
        record.render_detail = self.run.render_detail();
    }

    /// Render the current state (when the sink needs the image, or every frame when
    /// the scene has [`Runner::render_memory`]) and give it to `sink` (if it wants this
    /// frame), completing `record`.
    pub fn output(&mut self, record: &mut FrameRecord, sink: &mut dyn FrameSink) -> Result<(), RunError> {
        if !sink.wants(record.frame) {
            record.skipped = true;
            if self.render_memory.is_some() {
                self.render(record);
            }
            return Ok(());
        }
        let rendered = sink.needs_image() || self.render_memory.is_some();
        if rendered {
            self.render(record);
        }
        let t = self.clock.stopwatch();
        let layers = self.run.layers();
        let output = Output {
            index: record.frame,
            frame: self.run.frame(),
            layers: &layers,
            rendered,
            exposure: self.exposure,
            record,
            data: self.run.as_products(),
        };
        sink.write(&output).map_err(|error| RunError::Sink { frame: record.frame, error })?;
        record.write_ms = Some(t.ms());
        Ok(())
    }

    /// The checkpoint header of this scene at its current frame.
    pub fn checkpoint_header(&self) -> Header {
        self.run.header()
    }

    /// The whole simulation state now, as a checkpoint file's bytes.
    pub fn checkpoint(&self) -> Result<Vec<u8>, SinkError> {
        self.run.as_products().checkpoint()
    }

    /// Continue from checkpoint `bytes` of this scene (any frame at or after which the
    /// run goes on); returns the frames simulated. A checkpoint that is damaged, of
    /// another scene or seed, or whose state does not fit is refused and the runner is
    /// unchanged. A scene with [`Runner::render_memory`] refuses every checkpoint (its
    /// frames need the renders of the frames before).
    pub fn restore(&mut self, bytes: &[u8]) -> Result<u32, CheckpointError> {
        if let Some(why) = self.render_memory {
            return Err(CheckpointError::State(format!(
                "{why}, which a checkpoint (the simulation's state) does not hold: render from frame 0"
            )));
        }
        let (header, payload) = checkpoint::open(bytes)?;
        header.matches(&self.run.header())?;
        let frames = u32::try_from(header.frames_done)
            .map_err(|_| CheckpointError::State(format!("frame {} is out of range", header.frames_done)))?;
        self.run.restore(payload)?;
        Ok(frames)
    }

    /// Simulate up to frame `frames.end` (not included), rendering each frame of
    /// `frames` that `sink` wants into it; every simulated frame is reported to
    /// `observer`.
    pub fn run(
        &mut self,
        frames: Range<u32>,
        sink: &mut dyn FrameSink,
        observer: &mut dyn Observer,
    ) -> Result<(), RunError> {
        let at = self.frames_done();
        if frames.start < at && !frames.is_empty() {
            return Err(RunError::Past { asked: frames.start, at });
        }
        while self.frames_done() < frames.end {
            let mut record = self.step()?;
            if frames.contains(&record.frame) {
                self.output(&mut record, sink)?;
            } else if self.render_memory.is_some() {
                self.render(&mut record);
            }
            if observer.frame(&record).is_break() {
                return Err(RunError::Cancelled { frames: record.frame + 1 });
            }
        }
        sink.finish().map_err(|error| RunError::Sink { frame: frames.end.saturating_sub(1), error })
    }

    /// Export `name` of the current state in `format` (see the phenomenon's exports).
    pub fn export(&self, name: &str, format: &str) -> Result<Exported, String> {
        self.run.export(name, format)
    }

    /// Change `path` to `value` in the running simulation, if it can change live.
    pub fn steer(&mut self, path: &str, value: &Value) -> Steer {
        self.run.steer(path, value)
    }
}

/// A built phenomenon without its types.
pub(crate) trait Run: Send {
    fn step(&mut self) -> Result<Value, String>;
    fn render(&mut self, preview: Option<u32>);
    fn frame(&self) -> &Frame;
    fn layers(&self) -> Vec<Layer<'_>>;
    fn render_detail(&self) -> Option<Value>;
    fn set_clock(&mut self, clock: &SharedClock);
    fn export(&self, name: &str, format: &str) -> Result<Exported, String>;
    fn steer(&mut self, path: &str, value: &Value) -> Steer;
    fn warnings(&self) -> &[String];
    fn frames_done(&self) -> u64;
    fn header(&self) -> Header;
    fn restore(&mut self, payload: &[u8]) -> Result<(), CheckpointError>;
    fn as_products(&self) -> &dyn Products;
}

/// Build `scene`'s simulation and renderer: read its files, refuse it when its
/// estimate is over `limits`, build.
pub(crate) fn live<P: Phenomenon>(
    scene: &P,
    assets: &Assets,
    limits: &Limits,
) -> Result<(Box<dyn Run>, Estimate), BuildError> {
    let loaded = scene.load(assets)?;
    // The checks `validate` makes, so a render is refused with the same (located)
    // problems; the warnings come again from the build.
    scene.check(&loaded)?;
    let estimate = within(estimate(scene, &loaded), limits)?;
    let identity =
        checkpoint::identity(P::NAME, &checkpoint::simulation_tables(scene), P::files_identity(&loaded));
    let seed = scene.settings().seed;
    Ok((Box::new(Live { built: scene.build(loaded)?, identity, seed }), estimate))
}

/// `estimate` if it is within `limits`.
fn within(estimate: Estimate, limits: &Limits) -> Result<Estimate, BuildError> {
    if estimate.memory_bytes > limits.memory_bytes {
        return Err(BuildError::OverBudget {
            estimate: Box::new(estimate),
            limit_bytes: limits.memory_bytes,
        });
    }
    Ok(estimate)
}

/// The phenomenon's estimate plus writing a frame: the frame interleaved as f32 and as
/// 8-bit sRGB for PNG (EXR copies the planes, the same order of size).
fn estimate<P: Phenomenon>(scene: &P, loaded: &P::Loaded) -> Estimate {
    let mut e = scene.estimate(loaded);
    let (w, h) = scene.settings().size();
    let bytes = (w as u64) * (h as u64) * 15;
    e.parts.push(("writing a frame".into(), bytes));
    e.memory_bytes = e.memory_bytes.saturating_add(bytes);
    e
}

/// Read `scene`'s files and run its checks without building anything.
pub(crate) fn check<P: Phenomenon>(
    scene: &P,
    assets: &Assets,
    limits: &Limits,
) -> Result<Report, BuildError> {
    let loaded = scene.load(assets)?;
    let warnings = scene.check(&loaded)?;
    let estimate = within(estimate(scene, &loaded), limits)?;
    Ok(Report { warnings, estimate })
}

struct Live<P: Phenomenon> {
    built: Built<P>,
    /// The scene's checkpoint identity ([`checkpoint::identity`]).
    identity: u64,
    seed: u64,
}

impl<P: Phenomenon> Products for Live<P> {
    fn checkpoint(&self) -> Result<Vec<u8>, SinkError> {
        checkpoint::encode(&self.header(), &self.built.sim.state()).map_err(|e| SinkError(e.to_string()))
    }

    fn volume(
        &self,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut Vec<u8>,
    ) -> Result<Value, SinkError> {
        P::volume(&self.built, options, scratch, out).map_err(SinkError)
    }

    fn volume_bytes(&self, options: &VolumeOptions) -> Result<u64, SinkError> {
        P::volume_bytes(&self.built, options).map_err(SinkError)
    }

    fn points(&self) -> Result<Vec<u8>, SinkError> {
        let mut cache = P::points(&self.built).map_err(SinkError)?;
        cache.comments.push(format!("phenomena {} particles after {} frames", P::NAME, self.frames_done()));
        cache.to_ply().map_err(SinkError)
    }
}

impl<P: Phenomenon> Run for Live<P> {
    fn step(&mut self) -> Result<Value, String> {
        let stats = self.built.sim.step().map_err(|e| e.to_string())?;
        serde_json::to_value(stats).map_err(|e| e.to_string())
    }

    fn render(&mut self, preview: Option<u32>) {
        P::before_render(&mut self.built, preview);
        let Built { sim, renderer, .. } = &mut self.built;
        renderer.render(sim);
    }

    fn frame(&self) -> &Frame {
        self.built.renderer.frame()
    }

    fn layers(&self) -> Vec<Layer<'_>> {
        self.built.renderer.layers()
    }

    fn render_detail(&self) -> Option<Value> {
        P::render_detail(&self.built)
    }

    fn set_clock(&mut self, clock: &SharedClock) {
        P::set_clock(&mut self.built, clock)
    }

    fn export(&self, name: &str, format: &str) -> Result<Exported, String> {
        P::export(&self.built, name, format)
    }

    fn steer(&mut self, path: &str, value: &Value) -> Steer {
        P::steer(&mut self.built, path, value)
    }

    fn warnings(&self) -> &[String] {
        &self.built.warnings
    }

    fn frames_done(&self) -> u64 {
        self.built.sim.frames_done()
    }

    fn header(&self) -> Header {
        Header {
            phenomenon: P::NAME.to_string(),
            identity: self.identity,
            seed: self.seed,
            frames_done: self.frames_done(),
        }
    }

    fn restore(&mut self, payload: &[u8]) -> Result<(), CheckpointError> {
        let state = checkpoint::decode_state(payload)?;
        self.built.sim.restore(state).map_err(|e| CheckpointError::State(e.to_string()))
    }

    fn as_products(&self) -> &dyn Products {
        self
    }
}
