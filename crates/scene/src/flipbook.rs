//! The `flipbook` format: every frame of a run tiled into one RGBA atlas,
//! `flipbook.png`, with a JSON descriptor, `flipbook.json` ([`crate::atlas`]), for a
//! game engine's particle system or sprite shader. The frames are drawn over black (the
//! phenomenon's light alone: needs [`Capability::EmissionOnly`]); the atlas is written
//! when the run finishes, so a run cannot resume one.

use std::path::{Path, PathBuf};

use crate::atlas::{
    Atlas, Descriptor, FlipbookOptions, Layout, MOTION_ENCODING, MotionAtlas, MotionDescriptor,
};
use crate::error::SinkError;
use crate::format::{OutputFormat, Target};
use crate::output::{Files, ensure_dir, error, write_atomic, write_bytes_atomic};
use crate::phenomenon::{Capability, MotionVectors};
use crate::scene::Scene;
use crate::sink::{FrameSink, Output};

/// The format.
pub(crate) struct Flipbook;

impl OutputFormat for Flipbook {
    fn name(&self) -> &'static str {
        "flipbook"
    }

    fn about(&self) -> &'static str {
        "one atlas PNG of every frame and a JSON descriptor, for game engines"
    }

    fn needs(&self) -> Option<Capability> {
        Some(Capability::EmissionOnly)
    }

    fn resumable(&self) -> bool {
        false
    }

    fn prepare(&self, scene: &mut Scene) -> Result<(), String> {
        scene.emission_only()
    }

    fn open(&self, target: &Target<'_>) -> Result<Box<dyn Files>, SinkError> {
        if target.resume {
            return Err(SinkError(
                "--resume keeps finished frame files; a flipbook is one file made of every frame: render it again without --resume".into(),
            ));
        }
        let s = target.options.flipbook;
        if s.motion && !target.phenomenon.can(Capability::Motion) {
            return Err(SinkError(format!(
                "--motion: {} scenes have no motion vectors (the flame's do: its gas moves on screen)",
                target.phenomenon.name()
            )));
        }
        let options = FlipbookOptions {
            power_of_two: s.power_of_two,
            alpha: s.alpha,
            loop_frames: s.loop_frames,
            crop: s.crop,
            motion: s.motion,
            fps: target.fps,
        };
        let (w, h) = target.size;
        Ok(Box::new(FlipbookSink::new(target.dir, target.frames, w, h, options)?))
    }
}

/// All the frames of a run as one flipbook ([`crate::atlas`]): `DIR/flipbook.png`
/// (RGBA) and `DIR/flipbook.json`, written when the run finishes.
struct FlipbookSink {
    dir: PathBuf,
    options: FlipbookOptions,
    layout: Layout,
    atlas: Option<Atlas>,
    /// With `--motion`.
    motion: Option<MotionAtlas>,
    first: Option<u32>,
    last: u32,
}

impl FlipbookSink {
    /// A flipbook of `rendered` frames of `width × height` into `dir` (created if
    /// missing), refused at once when it cannot be laid out.
    fn new(
        dir: &Path,
        rendered: u32,
        width: u32,
        height: u32,
        options: FlipbookOptions,
    ) -> Result<Self, SinkError> {
        let layout = crate::atlas::layout(rendered, width, height, &options).map_err(SinkError)?;
        ensure_dir(dir)?;
        Ok(Self {
            dir: dir.to_path_buf(),
            options,
            layout,
            atlas: Some(Atlas::new(layout, options)),
            motion: options.motion.then(|| MotionAtlas::new(layout, options.loop_frames)),
            first: None,
            last: 0,
        })
    }

    /// The atlas image's path.
    fn image_path(&self) -> PathBuf {
        self.dir.join("flipbook.png")
    }
}

impl FrameSink for FlipbookSink {
    fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
        let (w, h) = (self.layout.frame_width as usize, self.layout.frame_height as usize);
        let frame = if (out.frame.width(), out.frame.height()) == (w, h) {
            std::borrow::Cow::Borrowed(out.frame)
        } else {
            std::borrow::Cow::Owned(out.frame.resized(w, h))
        };
        let linear = frame.to_interleaved();
        let mut display = Vec::with_capacity(linear.len());
        out.exposure.apply_all(&linear, |v| display.push(v));
        self.atlas
            .as_mut()
            .ok_or_else(|| error("the flipbook is already written"))?
            .push(display)
            .map_err(SinkError)?;
        if let Some(motion) = self.motion.as_mut() {
            motion.push(resized_vectors(out.data.motion()?, w, h)).map_err(SinkError)?;
        }
        self.first.get_or_insert(out.index);
        self.last = out.index;
        Ok(())
    }

    fn finish(&mut self) -> Result<(), SinkError> {
        let atlas = self.atlas.take().ok_or_else(|| error("the flipbook is already written"))?;
        let mut rgba = atlas.finish().map_err(SinkError)?;
        let mut motion = self.motion.take().map(MotionAtlas::finish).transpose().map_err(SinkError)?;
        let mut crop = None;
        if self.options.crop
            && let Some(rect) = crate::atlas::content_bounds(&rgba, &self.layout, self.options.power_of_two)
        {
            if let Some((m, _)) = motion.as_mut() {
                *m = crate::atlas::cropped(m, &self.layout, rect).0;
            }
            (rgba, self.layout) = crate::atlas::cropped(&rgba, &self.layout, rect);
            crop = Some(rect);
        }
        let (w, h) = (self.layout.atlas_width, self.layout.atlas_height);
        let image = self.image_path();
        write_atomic(&image, |tmp| {
            image::save_buffer_with_format(tmp, &rgba, w, h, image::ColorType::Rgba8, image::ImageFormat::Png)
                .map_err(error)
        })?;
        let descriptor = Descriptor {
            image: "flipbook.png".into(),
            layout: self.layout,
            fps: self.options.fps,
            alpha: self.options.alpha,
            loop_frames: self.options.loop_frames,
            order: "row-major from the top left",
            color_space: "sRGB",
            source_frames: [self.first.unwrap_or(0), self.last + 1],
            crop,
            motion: motion.as_ref().map(|&(_, scale_px)| MotionDescriptor {
                image: MOTION_IMAGE.into(),
                scale_px,
                encoding: MOTION_ENCODING,
            }),
        };
        if let Some((m, _)) = &motion {
            write_atomic(&self.dir.join(MOTION_IMAGE), |tmp| {
                image::save_buffer_with_format(tmp, m, w, h, image::ColorType::Rgba8, image::ImageFormat::Png)
                    .map_err(error)
            })?;
        }
        let json = serde_json::to_string_pretty(&descriptor).map_err(error)?;
        write_bytes_atomic(&self.dir.join("flipbook.json"), json.as_bytes())
    }
}

/// The motion atlas's file name.
const MOTION_IMAGE: &str = "flipbook_motion.png";

/// `m` resampled to `w` × `h` (bilinear, at pixel centres), its vectors scaled to the
/// new pixels.
fn resized_vectors(m: MotionVectors, w: usize, h: usize) -> Vec<[f32; 2]> {
    if (m.width, m.height) == (w, h) || m.width == 0 || m.height == 0 {
        return m.vectors;
    }
    let (sx, sy) = (m.width as f32 / w as f32, m.height as f32 / h as f32);
    let at = |x: usize, y: usize| m.vectors[y.min(m.height - 1) * m.width + x.min(m.width - 1)];
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        let fy = ((y as f32 + 0.5) * sy - 0.5).max(0.0);
        let (y0, ty) = (fy as usize, fy.fract());
        for x in 0..w {
            let fx = ((x as f32 + 0.5) * sx - 0.5).max(0.0);
            let (x0, tx) = (fx as usize, fx.fract());
            let v = [0, 1].map(|c| {
                let top = at(x0, y0)[c] * (1.0 - tx) + at(x0 + 1, y0)[c] * tx;
                let bottom = at(x0, y0 + 1)[c] * (1.0 - tx) + at(x0 + 1, y0 + 1)[c] * tx;
                top * (1.0 - ty) + bottom * ty
            });
            out.push([v[0] / sx, v[1] / sy]);
        }
    }
    out
}

impl Files for FlipbookSink {
    fn finished(&self, _index: u32) -> bool {
        false
    }

    fn counts(&self) -> (u32, u32) {
        (self.layout.frames, 0)
    }

    /// The atlas, the loop's head frames and one frame resized to its cell.
    fn memory_bytes(&self, _state: crate::sink::State<'_>) -> Result<u64, SinkError> {
        let cell = u64::from(self.layout.frame_width) * u64::from(self.layout.frame_height);
        // With motion, a frame's vectors as they are made (the renderer's frame: its
        // sums and vectors, 20 bytes a pixel) and resized to the cell (8).
        let motion = if self.options.motion { cell * 28 } else { 0 };
        Ok(Atlas::memory_bytes(&self.layout, &self.options) + cell * 24 + motion)
    }

    fn summary(&self, _dir: &Path) -> String {
        let l = self.layout;
        format!(
            "wrote a flipbook of {} frame(s) in {}x{} cells of {}x{} ({}x{} pixels) to {}",
            l.frames,
            l.columns,
            l.rows,
            l.frame_width,
            l.frame_height,
            l.atlas_width,
            l.atlas_height,
            self.image_path().display()
        )
    }
}
