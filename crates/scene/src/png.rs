//! The `png` format: each frame as `frame_NNNNN.png`, 8-bit sRGB, exposed and tone
//! mapped by the scene's `[scene]` settings.

use std::path::Path;

use crate::error::SinkError;
use crate::format::{OutputFormat, Target};
use crate::output::{Files, NumberedFiles, PerFrame, to_srgb8, write_png_rgb8};
use crate::sink::Output;

/// The format.
pub(crate) struct Png;

impl OutputFormat for Png {
    fn name(&self) -> &'static str {
        "png"
    }

    fn about(&self) -> &'static str {
        "8-bit sRGB PNG frames, exposed and tone mapped"
    }

    fn open(&self, target: &Target<'_>) -> Result<Box<dyn Files>, SinkError> {
        Ok(Box::new(NumberedFiles::new(target.dir, target.resume, PngFrames)?))
    }
}

/// Writes one PNG per frame.
struct PngFrames;

impl PerFrame for PngFrames {
    fn extension(&self) -> &'static str {
        "png"
    }

    fn needs_image(&self) -> bool {
        true
    }

    fn write(&mut self, path: &Path, out: &Output<'_>) -> Result<(), SinkError> {
        let (w, h) = (out.frame.width() as u32, out.frame.height() as u32);
        write_png_rgb8(path, w, h, &to_srgb8(out.frame, &out.exposure))
    }
}
