//! The `exr` format: each frame as `frame_NNNNN.exr`, 32-bit float linear radiance
//! (scene-referred, no tone mapping), with the renderer's layers as extra channels
//! named as they give them (`aurora_557_7.Y`).

use std::path::Path;

use phenomena_core::image::Frame;
use phenomena_core::phenomenon::Layer;

use crate::error::SinkError;
use crate::format::{OutputFormat, Target};
use crate::output::{Files, NumberedFiles, PerFrame, error, write_atomic};
use crate::sink::Output;

/// The format.
pub(crate) struct Exr;

impl OutputFormat for Exr {
    fn name(&self) -> &'static str {
        "exr"
    }

    fn about(&self) -> &'static str {
        "32-bit float linear OpenEXR frames (scene-referred radiance, no tone mapping), with the renderer's layers"
    }

    fn open(&self, target: &Target<'_>) -> Result<Box<dyn Files>, SinkError> {
        Ok(Box::new(NumberedFiles::new(target.dir, target.resume, ExrFrames)?))
    }
}

/// Writes one OpenEXR file per frame.
struct ExrFrames;

impl PerFrame for ExrFrames {
    fn extension(&self) -> &'static str {
        "exr"
    }

    fn needs_image(&self) -> bool {
        true
    }

    fn write(&mut self, path: &Path, out: &Output<'_>) -> Result<(), SinkError> {
        write_exr(path, out.frame, out.layers)
    }
}

/// Write `frame` as a linear OpenEXR file, with `layers` as extra channels, atomically.
/// One thread, blocks in order: the same pixels give the same bytes (the parallel
/// writer emits compressed blocks in completion order).
pub fn write_exr(path: &Path, frame: &Frame, layers: &[Layer<'_>]) -> Result<(), SinkError> {
    use exr::prelude::*;
    if layers.is_empty() {
        return write_atomic(path, |tmp| {
            let data = frame.to_interleaved();
            let width = frame.width();
            let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
                let i = (y * width + x) * 3;
                (data[i], data[i + 1], data[i + 2])
            });
            Image::from_channels((frame.width(), frame.height()), channels)
                .write()
                .non_parallel()
                .to_file(tmp)
                .map_err(error)
        });
    }
    write_atomic(path, |tmp| {
        let mut list: Vec<AnyChannel<FlatSamples>> = vec![
            AnyChannel::new("R", FlatSamples::F32(frame.c0.data().to_vec())),
            AnyChannel::new("G", FlatSamples::F32(frame.c1.data().to_vec())),
            AnyChannel::new("B", FlatSamples::F32(frame.c2.data().to_vec())),
        ];
        for layer in layers {
            list.push(AnyChannel::new(layer.name, FlatSamples::F32(layer.plane.data().to_vec())));
        }
        Image::from_channels((frame.width(), frame.height()), AnyChannels::sort(SmallVec::from_vec(list)))
            .write()
            .non_parallel()
            .to_file(tmp)
            .map_err(error)
    })
}
