//! Scene files of phenomena, and the one loop that turns them into frames.
//!
//! - [`parse`] reads a scene file (TOML: a `[scene]` table and one phenomenon's tables)
//!   and reports every problem at its line and column.
//! - [`registry`] lists the phenomena ([`registry::PHENOMENA`]: each an [`Entry`], one
//!   module such as [`flame`], [`aurora`], [`snow`], [`sparkle`] implementing
//!   [`Phenomenon`]) and the output formats ([`registry::FORMATS`]: each a [`Format`],
//!   one module implementing [`OutputFormat`]); [`shipped`] the scenes in `scenes/`.
//! - [`Assets`] is the only way a scene reads a file: from a folder, a studio session's
//!   sandbox, or memory.
//! - [`Runner`] builds a scene's simulation and renderer and runs them, handing frames
//!   to a [`FrameSink`]; [`job::render`] renders to files in a format, resuming and
//!   starting from checkpoints ([`checkpoint`]'s format, from which [`Runner::restore`]
//!   continues).
//!
//! A game or tool can load and run a scene with this crate alone:
//!
//! ```
//! use phenomena_scene::{Assets, FrameSink, Output, Runner, SinkError, parse};
//! let text = "[scene]\nframes = 3\nwidth = 64\nheight = 36\n[flame]\n[flame.emitter]\nrate_per_s = 600.0\n";
//! let scene = parse(text, "fire.toml").unwrap();
//! assert_eq!(scene.phenomenon().name(), "flame");
//!
//! /// Keeps the brightest value of each frame.
//! struct Peaks(Vec<f32>);
//! impl FrameSink for Peaks {
//!     fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
//!         self.0.push(out.frame.c0.data().iter().fold(0.0, |a, &b| a.max(b)));
//!         Ok(())
//!     }
//! }
//! let mut runner = Runner::new(&scene, &Assets::none()).unwrap();
//! let mut peaks = Peaks(Vec::new());
//! runner.run(1..3, &mut peaks, &mut ()).unwrap();
//! assert_eq!(peaks.0.len(), 2); // frames 1 and 2 (frame 0 is simulated, not drawn)
//! ```
//!
//! # Feature flags
//! - `dxf` (default): DXF snow meshes (off for `wasm32-unknown-unknown` builds).
//!
//! Unlike the phenomenon crates, this crate touches files: [`Assets`] reads them and
//! [`output`] writes them. It never prints and reads no clock (timings come from the
//! clock the caller gives [`Runner::set_clock`]).

pub mod assets;
pub mod atlas;
pub mod aurora;
mod budget;
pub mod cache;
pub mod checkpoint;
mod entry;
mod error;
mod exr;
pub mod flame;
mod flipbook;
pub mod format;
pub mod job;
pub mod output;
mod parse;
mod phenomenon;
mod ply;
mod png;
pub mod registry;
mod runner;
mod scene;
mod settings;
pub mod shipped;
pub mod shot;
mod sink;
pub mod snow;
mod source;
pub mod sparkle;
mod vdb;

pub use assets::{AssetError, Assets};
pub use budget::{Estimate, Limits, Report, gib};
pub use entry::Entry;
pub use error::{BuildError, RunError, SinkError};
pub use exr::write_exr;
pub use format::{Format, OutputFormat, OutputOptions};
pub use parse::{LoadError, MAX_SCENE_BYTES, load, parse};
pub use phenomenon::{
    Built, Capability, ExportKind, Exported, LeafGrid, MotionVectors, PASSES, Pass, Phenomenon, Scratch,
    Stage, Steer, View, VolumeOptions, VolumeOut, encode_volume,
};
pub use runner::Runner;
pub use scene::{Scene, set_path};
pub use settings::{MAX_SIDE_PX, SceneSettings};
pub use sink::{FrameRecord, FrameSink, Observer, Only, Output, Simulate, State, Tee};
pub use source::{Located, SceneErrors};
