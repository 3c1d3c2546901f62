//! Output formats: a format is one module implementing [`OutputFormat`] (`png.rs`,
//! `exr.rs`, `vdb.rs`, `ply.rs`, `flipbook.rs`) and one line in
//! [`crate::registry::FORMATS`]; what a phenomenon must give for it
//! ([`OutputFormat::needs`], a [`Capability`]) decides which phenomena offer it. The
//! CLI's `--format`, the studio's menu and the contract tests (every format × every
//! phenomenon, `tests/contract.rs`) read that list.

use std::fmt;
use std::path::Path;

use crate::atlas::FlipbookSettings;
use crate::entry::Entry;
use crate::error::SinkError;
use crate::output::Files;
use crate::phenomenon::{Capability, VolumeOptions};
use crate::scene::Scene;

/// How a format writes a run's frames.
pub trait OutputFormat: Sync {
    /// The name on the command line (`png`).
    fn name(&self) -> &'static str;
    /// One line on what it writes.
    fn about(&self) -> &'static str;
    /// What a phenomenon must be able to give for this format (`None`: images only,
    /// which every phenomenon draws).
    fn needs(&self) -> Option<Capability> {
        None
    }
    /// Whether a run can keep the frames an earlier run finished (`--resume`).
    fn resumable(&self) -> bool {
        true
    }
    /// Change the scene for this format before it is built (a flipbook draws the
    /// light alone over black).
    fn prepare(&self, _scene: &mut Scene) -> Result<(), String> {
        Ok(())
    }
    /// Open the files of a run.
    fn open(&self, target: &Target<'_>) -> Result<Box<dyn Files>, SinkError>;
}

/// Where and how a run writes its frames.
pub struct Target<'a> {
    /// The phenomenon written.
    pub phenomenon: crate::Entry,
    /// The folder (created if missing).
    pub dir: &'a Path,
    /// Frames the run writes.
    pub frames: u32,
    /// Frame width and height, pixels.
    pub size: (u32, u32),
    /// Frames per second of simulated time (a flipbook's playback rate).
    pub fps: f64,
    /// Keep frames an earlier run finished.
    pub resume: bool,
    /// The formats' options.
    pub options: &'a OutputOptions,
}

/// The options of every format (each reads its own).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OutputOptions {
    /// `vdb`: voxel size and memory limit.
    pub volume: VolumeOptions,
    /// `flipbook`: layout, alpha and loop.
    pub flipbook: FlipbookSettings,
}

/// An output format (one of [`crate::registry::FORMATS`]).
#[derive(Clone, Copy)]
pub struct Format(&'static dyn OutputFormat);

impl Format {
    /// The format implemented by `format` (for the registry's list).
    pub const fn new(format: &'static dyn OutputFormat) -> Self {
        Format(format)
    }
}

impl Format {
    /// The name on the command line (`png`).
    pub fn name(self) -> &'static str {
        self.0.name()
    }

    /// One line on what it writes.
    pub fn about(self) -> &'static str {
        self.0.about()
    }

    /// Whether phenomenon `entry` can be written in this format.
    pub fn writes(self, entry: Entry) -> bool {
        self.0.needs().is_none_or(|c| entry.can(c))
    }

    /// Whether a run can keep the frames an earlier run finished.
    pub fn resumable(self) -> bool {
        self.0.resumable()
    }

    /// Prepare `scene` for this format (once [`Format::check`] said it writes it).
    pub fn prepare(self, scene: &mut Scene) -> Result<(), String> {
        self.0.prepare(scene)
    }

    /// Open the files of a run.
    pub fn open(self, target: &Target<'_>) -> Result<Box<dyn Files>, SinkError> {
        self.0.open(target)
    }
}

impl PartialEq for Format {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
    }
}

impl Eq for Format {}

impl fmt::Debug for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Format({})", self.name())
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
