//! The `vdb` format: each frame as `frame_NNNNN.vdb`, the phenomenon's state as OpenVDB
//! grids ([`crate::Phenomenon::volume`]), with a manifest beside it
//! (`frame_NNNNN.vdb.json`: each grid as OpenVDB will report it). The manifest is
//! written first, so a volume beside its manifest is whole. Needs
//! [`Capability::Volume`].

use std::path::Path;

use crate::error::SinkError;
use crate::format::{OutputFormat, Target};
use crate::output::{
    Files, NumberedFiles, PerFrame, error, manifest_path, remove_if_there, write_bytes_atomic,
};
use crate::phenomenon::{Capability, Scratch, VolumeOptions, VolumeOut};
use crate::sink::{Output, State};

/// The format.
pub(crate) struct Vdb;

impl OutputFormat for Vdb {
    fn name(&self) -> &'static str {
        "vdb"
    }

    fn about(&self) -> &'static str {
        "OpenVDB volumes, one per frame, each with a JSON manifest"
    }

    fn needs(&self) -> Option<Capability> {
        Some(Capability::Volume)
    }

    fn open(&self, target: &Target<'_>) -> Result<Box<dyn Files>, SinkError> {
        let writer =
            VolumeFrames { options: target.options.volume, scratch: Scratch::default(), bytes: Vec::new() };
        Ok(Box::new(NumberedFiles::new(target.dir, target.resume, writer)?))
    }
}

/// Writes one volume and its manifest per frame, keeping the grids' buffers.
struct VolumeFrames {
    options: VolumeOptions,
    scratch: Scratch,
    bytes: Vec<u8>,
}

impl PerFrame for VolumeFrames {
    fn extension(&self) -> &'static str {
        "vdb"
    }

    fn needs_image(&self) -> bool {
        false
    }

    fn write(&mut self, path: &Path, out: &Output<'_>) -> Result<(), SinkError> {
        let mut manifest =
            out.data.volume(&self.options, &mut self.scratch, &mut VolumeOut::Vdb(&mut self.bytes))?;
        manifest["frame"] = out.index.into();
        let text = serde_json::to_string_pretty(&manifest).map_err(error)?;
        // The manifest first: a volume is never left without one (a failure between
        // the two leaves a manifest alone, which a resumed render writes again).
        remove_if_there(path);
        write_bytes_atomic(&manifest_path(path), text.as_bytes())?;
        write_bytes_atomic(path, &self.bytes)
    }

    fn finished(&self, path: &Path) -> bool {
        path.is_file() && manifest_path(path).is_file()
    }

    fn memory_bytes(&self, state: State<'_>) -> Result<u64, SinkError> {
        state.volume_bytes(&self.options)
    }

    fn limit_memory(&mut self, max_bytes: u64) {
        self.options.max_bytes = Some(max_bytes);
    }
}
