//! The one render loop: build a scene's simulation and renderer ([`Runner::new`]), step
//! it frame by frame and hand the frames wanted to a [`FrameSink`] (PNG or EXR files,
//! the studio's preview, ...), reporting each frame to an [`Observer`] (progress,
//! statistics, cancellation). `render`, `demo`, `export`, the studio's preview and its
//! final renders all run through it ([`crate::job`] adds files, resume and checkpoints).

use std::ops::Range;

use phenomena_core::clock::SharedClock;
use phenomena_core::image::Frame;
use phenomena_core::tonemap::Exposure;
use serde_json::Value;

use crate::assets::Assets;
use crate::budget::{Estimate, Limits};
use crate::checkpoint::{self, CheckpointError, Header};
use crate::entry::{BuiltBox, Entry};
use crate::error::{BuildError, RunError, SinkError};
use crate::phenomenon::{Exported, Steer, VolumeOptions};
use crate::scene::Scene;
use crate::sink::{FrameRecord, FrameSink, Observer, Output, State};

/// A phenomenon's simulation and renderer, stepped together.
pub struct Runner {
    entry: Entry,
    built: BuiltBox,
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
        let (built, estimate) = scene.build(assets, limits)?;
        Ok(Self {
            entry: scene.phenomenon(),
            built,
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
        self.entry.ops().set_clock(&mut *self.built, &clock);
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

    /// The simulation's state now (checkpoints, volumes, point caches).
    pub fn state(&self) -> State<'_> {
        State { entry: self.entry, built: &*self.built }
    }

    /// Its phenomenon.
    pub fn phenomenon(&self) -> Entry {
        self.entry
    }

    /// Add what writing the frames takes (`parts`: what, bytes; a flipbook's atlas, a
    /// volume's grids) to the estimate, refused like [`Runner::with_limits`] when the
    /// whole is over `limits`: checked before the first frame.
    pub fn admit(&mut self, parts: Vec<(String, u64)>, limits: &Limits) -> Result<(), BuildError> {
        let mut estimate = self.estimate.clone();
        for (what, bytes) in parts {
            estimate = estimate.with(what, bytes);
        }
        self.estimate = estimate.within(limits)?;
        Ok(())
    }

    /// Bytes a volume of the current state at `options` takes (an upper bound that
    /// allows for the state's growth), checking the voxel size.
    pub fn volume_bytes(&self, options: &VolumeOptions) -> Result<u64, SinkError> {
        self.state().volume_bytes(options)
    }

    /// Warnings found while building (each a sentence).
    pub fn warnings(&self) -> &[String] {
        self.entry.ops().warnings(&*self.built)
    }

    /// Frames simulated so far.
    pub fn frames_done(&self) -> u32 {
        u32::try_from(self.entry.ops().frames_done(&*self.built)).unwrap_or(u32::MAX)
    }

    /// The frame of the last render.
    pub fn frame(&self) -> &Frame {
        self.entry.ops().frame(&*self.built)
    }

    /// Simulate one frame.
    pub fn step(&mut self) -> Result<FrameRecord, RunError> {
        let frame = self.frames_done();
        let t = self.clock.stopwatch();
        let counters =
            self.entry.ops().step(&mut *self.built).map_err(|message| RunError::Step { frame, message })?;
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
        record.ahead_ms =
            self.entry.ops().render(&mut *self.built, self.preview.then_some(done), &self.clock);
        record.render_ms = Some(t.ms());
        record.render_detail = self.entry.ops().render_detail(&*self.built);
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
        let layers = self.entry.ops().layers(&*self.built);
        let output = Output {
            index: record.frame,
            frame: self.entry.ops().frame(&*self.built),
            layers: &layers,
            rendered,
            exposure: self.exposure,
            record,
            data: self.state(),
        };
        sink.write(&output).map_err(|error| RunError::Sink { frame: record.frame, error })?;
        record.write_ms = Some(t.ms());
        Ok(())
    }

    /// The checkpoint header of this scene at its current frame.
    pub fn checkpoint_header(&self) -> Header {
        self.entry.ops().header(&*self.built)
    }

    /// The whole simulation state now, as a checkpoint file's bytes.
    pub fn checkpoint(&self) -> Result<Vec<u8>, SinkError> {
        self.state().checkpoint()
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
        header.matches(&self.entry.ops().header(&*self.built))?;
        let frames = u32::try_from(header.frames_done)
            .map_err(|_| CheckpointError::State(format!("frame {} is out of range", header.frames_done)))?;
        self.entry.ops().restore(&mut *self.built, payload)?;
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
        self.entry.ops().export(&*self.built, name, format)
    }

    /// Change `path` to `value` in the running simulation, if it can change live.
    pub fn steer(&mut self, path: &str, value: &Value) -> Steer {
        self.entry.ops().steer(&mut *self.built, path, value)
    }
}
