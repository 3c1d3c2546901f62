//! The `ply` format: each frame as `frame_NNNNN.ply`, the phenomenon's particles as a
//! binary little-endian PLY point cache ([`crate::Phenomenon::points`]). Needs
//! [`Capability::Points`].

use std::path::Path;

use crate::error::SinkError;
use crate::format::{OutputFormat, Target};
use crate::output::{Files, NumberedFiles, PerFrame, write_bytes_atomic};
use crate::phenomenon::Capability;
use crate::sink::Output;

/// The format.
pub(crate) struct Ply;

impl OutputFormat for Ply {
    fn name(&self) -> &'static str {
        "ply"
    }

    fn about(&self) -> &'static str {
        "binary PLY particle caches, one per frame"
    }

    fn needs(&self) -> Option<Capability> {
        Some(Capability::Points)
    }

    fn open(&self, target: &Target<'_>) -> Result<Box<dyn Files>, SinkError> {
        Ok(Box::new(NumberedFiles::new(target.dir, target.resume, PointFrames)?))
    }
}

/// Writes one point cache per frame.
struct PointFrames;

impl PerFrame for PointFrames {
    fn extension(&self) -> &'static str {
        "ply"
    }

    fn needs_image(&self) -> bool {
        false
    }

    fn write(&mut self, path: &Path, out: &Output<'_>) -> Result<(), SinkError> {
        write_bytes_atomic(path, &out.data.points()?)
    }
}
