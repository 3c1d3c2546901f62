//! Writing files: every output goes to a temporary name in the same directory and is
//! renamed into place, so a crash or Ctrl-C never leaves a half-written file.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use phenomena_core::color::srgb_encode_u8_fast;
use phenomena_core::image::{Frame, Plane};
use phenomena_core::tonemap::Exposure;

/// Image formats for frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum ImageFormat {
    /// 8-bit sRGB PNG, exposed and tone mapped.
    Png,
    /// 32-bit float linear OpenEXR (scene-referred radiance, no tone mapping).
    Exr,
}

impl ImageFormat {
    pub(crate) fn extension(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Exr => "exr",
        }
    }
}

/// The temporary name used while writing `path`: `.NAME.tmp` beside it.
fn temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp"))
}

/// Write `path` atomically with a closure that writes the temporary file.
pub(crate) fn write_atomic(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = temp_path(path);
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path)
            .with_context(|| format!("cannot rename {} to {}", tmp.display(), path.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Write bytes atomically.
pub(crate) fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |tmp| {
        let mut f = std::fs::File::create(tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
        f.write_all(bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
        f.sync_all().ok();
        Ok(())
    })
}

/// Tone map a linear frame to 8-bit sRGB bytes (row-major RGB triples).
pub(crate) fn to_srgb8(frame: &Frame, exposure: &Exposure) -> Vec<u8> {
    use rayon::prelude::*;
    // Each value maps on its own, so chunks in parallel give the same bytes.
    const CHUNK: usize = 1 << 14;
    let linear = frame.to_interleaved();
    let mut out = vec![0u8; linear.len()];
    out.par_chunks_mut(CHUNK).zip(linear.par_chunks(CHUNK)).for_each(|(o, l)| {
        let mut k = 0;
        exposure.apply_all(l, |v| {
            o[k] = srgb_encode_u8_fast(v);
            k += 1;
        });
    });
    out
}

/// Write a frame as PNG (tone mapped) or EXR (linear, with `layers` as extra
/// channels named as given, e.g. `aurora_557_7.Y`), atomically.
pub(crate) fn write_frame(
    path: &Path,
    frame: &Frame,
    layers: &[(String, &Plane)],
    format: ImageFormat,
    exposure: &Exposure,
) -> Result<()> {
    let (w, h) = (frame.width() as u32, frame.height() as u32);
    match format {
        ImageFormat::Png => write_png_rgb8(path, w, h, &to_srgb8(frame, exposure)),
        ImageFormat::Exr if !layers.is_empty() => write_atomic(path, |tmp| {
            use exr::prelude::*;
            let mut list: Vec<AnyChannel<FlatSamples>> = vec![
                AnyChannel::new("R", FlatSamples::F32(frame.c0.data().to_vec())),
                AnyChannel::new("G", FlatSamples::F32(frame.c1.data().to_vec())),
                AnyChannel::new("B", FlatSamples::F32(frame.c2.data().to_vec())),
            ];
            for (name, plane) in layers {
                list.push(AnyChannel::new(name.as_str(), FlatSamples::F32(plane.data().to_vec())));
            }
            Image::from_channels((frame.width(), frame.height()), AnyChannels::sort(SmallVec::from_vec(list)))
                .write()
                .non_parallel()
                .to_file(tmp)
                .with_context(|| format!("cannot write {}", tmp.display()))
        }),
        ImageFormat::Exr => write_atomic(path, |tmp| {
            use exr::prelude::*;
            let data = frame.to_interleaved();
            let width = frame.width();
            let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
                let i = (y * width + x) * 3;
                (data[i], data[i + 1], data[i + 2])
            });
            // One thread, blocks in order: the same pixels give the same bytes (the
            // parallel writer emits compressed blocks in completion order).
            Image::from_channels((frame.width(), frame.height()), channels)
                .write()
                .non_parallel()
                .to_file(tmp)
                .with_context(|| format!("cannot write {}", tmp.display()))
        }),
    }
}

/// Write 8-bit RGB as PNG, atomically.
pub(crate) fn write_png_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    write_atomic(path, |tmp| {
        image::save_buffer_with_format(
            tmp,
            rgb,
            width,
            height,
            image::ColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .with_context(|| format!("cannot write {}", tmp.display()))
    })
}

/// Create `dir` (and parents) if missing; a clear error if that fails or it is a file.
pub(crate) fn ensure_dir(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        bail!("{} exists and is not a directory", dir.display());
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the output directory {}", dir.display()))?;
    // Probe writability now rather than after minutes of simulation.
    let probe = dir.join(".phenomena-write-test.tmp");
    std::fs::write(&probe, b"")
        .with_context(|| format!("the output directory {} is not writable", dir.display()))?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}

/// Load a PNG (or any format the `image` crate reads with its enabled features) as
/// 8-bit RGB.
pub(crate) fn read_rgb8(path: &Path) -> Result<(usize, usize, Vec<u8>)> {
    let img =
        image::open(path).with_context(|| format!("cannot read the image {}", path.display()))?.to_rgb8();
    Ok((img.width() as usize, img.height() as usize, img.into_raw()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_writes_leave_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        let r = write_atomic(&path, |tmp| {
            std::fs::write(tmp, b"partial")?;
            bail!("simulated failure")
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        write_bytes_atomic(&path, b"ok").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"ok");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
