//! Where a run's frames go: a [`FrameSink`] takes each frame it wants as an [`Output`]
//! (its image and the simulation's [`State`]); [`Only`] and [`Tee`] compose sinks, and an
//! [`Observer`] hears of every frame (progress, statistics, cancellation) and of what a
//! run notes on the way.

use std::any::Any;
use std::ops::{ControlFlow, Range};

use phenomena_core::image::Frame;
use phenomena_core::phenomenon::Layer;
use phenomena_core::tonemap::Exposure;
use serde::Serialize;
use serde_json::Value;

use crate::budget::Estimate;
use crate::entry::Entry;
use crate::error::SinkError;
use crate::phenomenon::{Scratch, VolumeOptions, VolumeOut};

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
    /// The next frame's step when it was taken on a spare beside this render (a snow
    /// scene's), ms: within `render_ms`, and the next frame's `step_ms` is then only
    /// taking it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ahead_ms: Option<f64>,
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
    pub data: State<'a>,
}

/// A simulation's state at a frame, for sinks that write data rather than pictures:
/// checkpoints, volumes, point caches.
#[derive(Clone, Copy)]
pub struct State<'a> {
    pub(crate) entry: Entry,
    pub(crate) built: &'a (dyn Any + Send),
}

impl State<'_> {
    /// A checkpoint of the whole state ([`crate::checkpoint`]'s format).
    pub fn checkpoint(&self) -> Result<Vec<u8>, SinkError> {
        self.entry.ops().checkpoint(self.built)
    }

    /// The state as an OpenVDB file's bytes, into `out` (cleared first), with buffers
    /// kept in `scratch` from frame to frame; returns the file's manifest
    /// ([`crate::phenomenon::encode_volume`]).
    pub fn volume(
        &self,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut VolumeOut<'_>,
    ) -> Result<Value, SinkError> {
        self.entry.ops().volume(self.built, options, scratch, out)
    }

    /// Bytes a volume at `options` takes (an upper bound allowing for growth), checking
    /// the voxel size ([`crate::Phenomenon::volume_bytes`]).
    pub fn volume_bytes(&self, options: &VolumeOptions) -> Result<u64, SinkError> {
        self.entry.ops().volume_bytes(self.built, options)
    }

    /// The particles as a binary PLY file's bytes.
    pub fn points(&self) -> Result<Vec<u8>, SinkError> {
        self.entry.ops().points(self.built)
    }

    /// The last rendered frame's motion vectors ([`crate::Phenomenon::motion`]).
    pub fn motion(&self) -> Result<crate::phenomenon::MotionVectors, SinkError> {
        self.entry.ops().motion(self.built)
    }
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

/// Told about every frame as it finishes (and may stop the run), and of what the run
/// notes on the way (a checkpoint not used, say).
pub trait Observer {
    /// Frame `record.frame` is done (stepped, and rendered if it was wanted).
    fn frame(&mut self, record: &FrameRecord) -> ControlFlow<()>;

    /// Something the user should hear of, a sentence (the CLI prints it as a warning).
    fn note(&mut self, _message: &str) {}

    /// The run's memory and work, estimated when its simulation was built.
    fn estimate(&mut self, _estimate: &Estimate) {}
}

impl Observer for () {
    fn frame(&mut self, _record: &FrameRecord) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
}
