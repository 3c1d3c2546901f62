//! Flipbook atlases for game engines: a render's frames tiled into one RGBA atlas
//! (rows × columns, row-major from the top left) with a JSON descriptor, the texture
//! sheet a particle system or a sprite shader plays. Assembly only; the `flipbook`
//! format (`flipbook.rs`) writes the files.
//!
//! Frames are rendered over black (the phenomenon's emission alone) and tone mapped as
//! PNG frames are; alpha is the largest of the three display-linear channels, the usual
//! coverage of an emissive sprite. `straight`: colour = value / alpha; `premultiplied`:
//! colour = value. Either way `colour · alpha` (or the premultiplied colour) over a
//! black background gives back the frame, and additive blending keeps the glow.
//!
//! `loop_frames = K` makes a seamless loop of N frames: the result has N − K frames,
//! the first K cross-faded with the K that follow the last, frame j (j < K) being
//! w_j · f_j + (1 − w_j) · f_{N−K+j} with w_j = (j + 1)/(K + 1), so the step from the
//! last frame back to the first is as small as any other step of the fade.

use serde::Serialize;

/// How the atlas stores alpha.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Alpha {
    /// Colour not multiplied by alpha.
    Straight,
    /// Colour multiplied by alpha.
    Premultiplied,
}

/// A flipbook's choices (the `flipbook` format's options; its rate comes from the
/// scene).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlipbookSettings {
    /// Cells and grid in powers of two (frames resampled to the cell size).
    pub power_of_two: bool,
    /// Straight or premultiplied alpha.
    pub alpha: Alpha,
    /// Frames cross-faded into the first for a seamless loop (0: no loop).
    pub loop_frames: u32,
    /// Cells cut to the content's bounds over every frame ([`content_bounds`]).
    pub crop: bool,
    /// A second atlas of motion vectors beside the colour ([`MotionAtlas`]).
    pub motion: bool,
}

impl Default for FlipbookSettings {
    fn default() -> Self {
        Self { power_of_two: false, alpha: Alpha::Straight, loop_frames: 0, crop: false, motion: false }
    }
}

/// Largest atlas side, pixels (what current engines and GPUs take).
pub const MAX_ATLAS_SIDE: u32 = 16384;

/// How to lay out a flipbook.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlipbookOptions {
    /// Cells and grid rounded to powers of two (frames resampled to the cell size).
    pub power_of_two: bool,
    /// Straight or premultiplied alpha.
    pub alpha: Alpha,
    /// Frames cross-faded into the first to make a loop (0: none).
    pub loop_frames: u32,
    /// Cells cut to the content's bounds over every frame ([`content_bounds`]).
    pub crop: bool,
    /// A second atlas of motion vectors ([`MotionAtlas`]).
    pub motion: bool,
    /// Playback rate, frames per second (the scene's).
    pub fps: f64,
}

/// The atlas's layout for `frames` frames of `width × height`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Layout {
    /// Frames in the atlas (after the loop's cross-fade).
    pub frames: u32,
    /// Columns of cells.
    pub columns: u32,
    /// Rows of cells.
    pub rows: u32,
    /// Cell width, pixels.
    pub frame_width: u32,
    /// Cell height, pixels.
    pub frame_height: u32,
    /// Atlas width, pixels.
    pub atlas_width: u32,
    /// Atlas height, pixels.
    pub atlas_height: u32,
}

/// The layout of `rendered` frames of `width × height` under `options`, or why there
/// cannot be one (a loop longer than half the frames, an atlas over
/// [`MAX_ATLAS_SIDE`]).
pub fn layout(rendered: u32, width: u32, height: u32, options: &FlipbookOptions) -> Result<Layout, String> {
    if rendered == 0 {
        return Err("a flipbook needs at least one frame".into());
    }
    if options.loop_frames > rendered / 2 {
        return Err(format!(
            "--loop {} needs at least {} frames: the cross-fade takes at most half of the {rendered} rendered",
            options.loop_frames,
            2 * options.loop_frames
        ));
    }
    let frames = rendered - options.loop_frames;
    let mut columns = (f64::from(frames).sqrt().ceil() as u32).max(1);
    let (mut w, mut h) = (width, height);
    if options.power_of_two {
        columns = columns.next_power_of_two();
        w = nearest_power_of_two(w);
        h = nearest_power_of_two(h);
    }
    let mut rows = frames.div_ceil(columns);
    if options.power_of_two {
        rows = rows.next_power_of_two();
    }
    let (aw, ah) = (u64::from(columns) * u64::from(w), u64::from(rows) * u64::from(h));
    if aw > u64::from(MAX_ATLAS_SIDE) || ah > u64::from(MAX_ATLAS_SIDE) {
        return Err(format!(
            "the atlas of {frames} frames of {w}x{h} would be {aw}x{ah} pixels, over {MAX_ATLAS_SIDE} a side: render smaller frames (--width, --height) or fewer (--frames)"
        ));
    }
    Ok(Layout {
        frames,
        columns,
        rows,
        frame_width: w,
        frame_height: h,
        atlas_width: aw as u32,
        atlas_height: ah as u32,
    })
}

/// The power of two nearest to `v` (in log scale; at least 1).
fn nearest_power_of_two(v: u32) -> u32 {
    let up = v.max(1).next_power_of_two();
    let down = (up / 2).max(1);
    if f64::from(v) / f64::from(down) < f64::from(up) / f64::from(v) { down } else { up }
}

/// Frames of display-linear RGB (interleaved, each `layout.frame_width ×
/// frame_height`) cross-faded for the loop and tiled into RGBA8 (sRGB colour) with
/// `options.alpha`; `frames.len()` must be `layout.frames + options.loop_frames`.
/// (All frames at once; [`Atlas`] builds the same bytes a frame at a time.)
pub fn atlas(frames: &[Vec<f32>], layout: &Layout, options: &FlipbookOptions) -> Result<Vec<u8>, String> {
    let k = options.loop_frames as usize;
    let n = layout.frames as usize;
    if frames.len() != n + k {
        return Err(format!("{} frames for a flipbook of {} (+{k} cross-faded)", frames.len(), n));
    }
    let mut atlas = Atlas::new(*layout, *options);
    for f in frames {
        atlas.push(f.clone())?;
    }
    atlas.finish()
}

/// An atlas built a frame at a time: each cell is encoded into the RGBA8 atlas as its
/// frame arrives, and only the first `loop_frames` frames are kept (as display-linear
/// floats) until the frames cross-faded into them arrive. Memory: the atlas and those
/// frames ([`Atlas::memory_bytes`]), not every frame.
pub struct Atlas {
    layout: Layout,
    options: FlipbookOptions,
    rgba: Vec<u8>,
    /// The loop's head frames, until their tails arrive.
    heads: Vec<Vec<f32>>,
    pushed: usize,
}

impl Atlas {
    /// An empty atlas of `layout`.
    pub fn new(layout: Layout, options: FlipbookOptions) -> Self {
        Self { layout, options, rgba: Vec::new(), heads: Vec::new(), pushed: 0 }
    }

    /// Bytes an atlas of `layout` holds at its peak: the RGBA8 image and the loop's
    /// head frames (and, when cropped, the cropped copy, at most as large).
    pub fn memory_bytes(layout: &Layout, options: &FlipbookOptions) -> u64 {
        let cell = u64::from(layout.frame_width) * u64::from(layout.frame_height);
        let image = u64::from(layout.atlas_width) * u64::from(layout.atlas_height) * 4;
        let colour = image * if options.crop { 2 } else { 1 } + u64::from(options.loop_frames) * cell * 12;
        // The motion atlas: its vectors (4 bytes a pixel), its image and crop, its heads.
        let motion = image * 2 + u64::from(options.loop_frames) * cell * 8;
        colour + if options.motion { motion } else { 0 }
    }

    /// The next frame (display-linear RGB, interleaved, the cell's size).
    pub fn push(&mut self, frame: Vec<f32>) -> Result<(), String> {
        let (k, n) = (self.options.loop_frames as usize, self.layout.frames as usize);
        let (fw, fh) = (self.layout.frame_width as usize, self.layout.frame_height as usize);
        if frame.len() != fw * fh * 3 {
            return Err(format!("a frame of {} values for cells of {fw}x{fh}", frame.len()));
        }
        if self.pushed >= n + k {
            return Err(format!("more than the {} frames of a flipbook of {n} (+{k} cross-faded)", n + k));
        }
        if self.rgba.is_empty() {
            self.rgba = vec![0u8; self.layout.atlas_width as usize * self.layout.atlas_height as usize * 4];
        }
        let j = self.pushed;
        self.pushed += 1;
        if j < k {
            self.heads.push(frame);
        } else if j < n {
            self.cell(j, &frame);
        } else {
            // Tail frame n + i fades into head i (`looped`'s weights).
            let i = j - n;
            let head = std::mem::take(&mut self.heads[i]);
            let w = (i + 1) as f32 / (k + 1) as f32;
            let faded: Vec<f32> = head.iter().zip(&frame).map(|(&a, &b)| w * a + (1.0 - w) * b).collect();
            self.cell(i, &faded);
        }
        Ok(())
    }

    /// Encode `values` into cell `j`.
    fn cell(&mut self, j: usize, values: &[f32]) {
        let (fw, fh) = (self.layout.frame_width as usize, self.layout.frame_height as usize);
        let aw = self.layout.atlas_width as usize;
        let (cx, cy) = (j % self.layout.columns as usize, j / self.layout.columns as usize);
        for y in 0..fh {
            let row = ((cy * fh + y) * aw + cx * fw) * 4;
            for x in 0..fw {
                let v = &values[(y * fw + x) * 3..(y * fw + x) * 3 + 3];
                self.rgba[row + x * 4..row + x * 4 + 4].copy_from_slice(&rgba(v, self.options.alpha));
            }
        }
    }

    /// The atlas's RGBA8 pixels, once every frame was pushed.
    pub fn finish(self) -> Result<Vec<u8>, String> {
        let (k, n) = (self.options.loop_frames as usize, self.layout.frames as usize);
        if self.pushed != n + k {
            return Err(format!("{} frames for a flipbook of {} (+{k} cross-faded)", self.pushed, n));
        }
        Ok(self.rgba)
    }
}

/// Motion vectors tiled as the colour atlas is (the same cells, cross-fade and crop),
/// encoded once the largest is known:
/// `R = 128 + round(127 · dx / scale_px)`, `G = 128 + round(127 · dy / scale_px)`
/// (8 bits each, so 128 is still), `B = 0`, `A = 255`,
/// with (dx, dy) the displacement of the cell's content from this frame to the next in
/// cell pixels, x to the right and y down, and `scale_px` the largest |dx| or |dy| over
/// every cell (before any crop). Until then each vector is kept as an i16 in steps of
/// 1/(32767 / the cell's longer side) pixel: a displacement up to the cell's size, far
/// finer than an 8-bit code. A flipbook shader blending frames k and k + 1 at t samples
/// frame k at uv − t·d and frame k + 1 at uv + (1 − t)·d, d in uv units (pixels over
/// the atlas's size).
pub struct MotionAtlas {
    layout: Layout,
    loop_frames: u32,
    /// Steps of a stored vector per pixel.
    steps_per_px: f32,
    /// Each atlas pixel's vector, in steps.
    steps: Vec<[i16; 2]>,
    heads: Vec<Vec<[f32; 2]>>,
    pushed: usize,
    largest: i16,
}

impl MotionAtlas {
    /// An empty motion atlas of `layout`.
    pub fn new(layout: Layout, loop_frames: u32) -> Self {
        let side = layout.frame_width.max(layout.frame_height).max(1);
        let steps_per_px = f32::from(i16::MAX) / side as f32;
        Self {
            layout,
            loop_frames,
            steps_per_px,
            steps: Vec::new(),
            heads: Vec::new(),
            pushed: 0,
            largest: 0,
        }
    }

    /// The next frame's vectors (cell pixels, the cell's size, row-major).
    pub fn push(&mut self, vectors: Vec<[f32; 2]>) -> Result<(), String> {
        let (k, n) = (self.loop_frames as usize, self.layout.frames as usize);
        let (fw, fh) = (self.layout.frame_width as usize, self.layout.frame_height as usize);
        if vectors.len() != fw * fh {
            return Err(format!("motion vectors of {} pixels for cells of {fw}x{fh}", vectors.len()));
        }
        if self.pushed >= n + k {
            return Err(format!("more than the {} frames of a flipbook of {n} (+{k} cross-faded)", n + k));
        }
        if self.steps.is_empty() {
            self.steps = vec![[0; 2]; self.layout.atlas_width as usize * self.layout.atlas_height as usize];
        }
        let j = self.pushed;
        self.pushed += 1;
        if j < k {
            self.heads.push(vectors);
        } else if j < n {
            self.cell(j, &vectors);
        } else {
            // As the colour: tail frame n + i fades into head i.
            let i = j - n;
            let head = std::mem::take(&mut self.heads[i]);
            let w = (i + 1) as f32 / (k + 1) as f32;
            let faded: Vec<[f32; 2]> =
                head.iter().zip(&vectors).map(|(a, b)| [0, 1].map(|c| w * a[c] + (1.0 - w) * b[c])).collect();
            self.cell(i, &faded);
        }
        Ok(())
    }

    fn cell(&mut self, j: usize, vectors: &[[f32; 2]]) {
        let (fw, fh) = (self.layout.frame_width as usize, self.layout.frame_height as usize);
        let aw = self.layout.atlas_width as usize;
        let (cx, cy) = (j % self.layout.columns as usize, j / self.layout.columns as usize);
        let limit = f32::from(i16::MAX);
        for y in 0..fh {
            let row = (cy * fh + y) * aw + cx * fw;
            for x in 0..fw {
                // Beyond the cell's size (or infinite): held at the largest step; not a
                // number: still.
                let q = vectors[y * fw + x].map(|v| {
                    if v.is_nan() { 0 } else { (v * self.steps_per_px).round().clamp(-limit, limit) as i16 }
                });
                self.largest = self.largest.max(q[0].abs()).max(q[1].abs());
                self.steps[row + x] = q;
            }
        }
    }

    /// The atlas's RGBA8 pixels and its scale (pixels), once every frame was pushed.
    pub fn finish(self) -> Result<(Vec<u8>, f32), String> {
        let (k, n) = (self.loop_frames as usize, self.layout.frames as usize);
        if self.pushed != n + k {
            return Err(format!("{} motion frames for a flipbook of {} (+{k} cross-faded)", self.pushed, n));
        }
        let scale = f32::from(self.largest.max(1));
        let byte = |v: i16| (128.0 + (127.0 * f32::from(v) / scale).round()) as u8;
        let rgba = self.steps.iter().flat_map(|&[x, y]| [byte(x), byte(y), 0, 255]).collect();
        Ok((rgba, scale / self.steps_per_px))
    }
}

/// How the motion atlas is written, for the descriptor.
#[derive(Clone, Debug, Serialize)]
pub struct MotionDescriptor {
    /// The motion atlas's file name.
    pub image: String,
    /// The largest displacement component, cell pixels: R and G hold
    /// 128 + round(127 · d / scale_px).
    pub scale_px: f32,
    /// The encoding in words.
    pub encoding: &'static str,
}

/// [`MotionDescriptor::encoding`].
pub const MOTION_ENCODING: &str = "linear 8-bit R, G = 128 + round(127 * d / scale_px), so d = (byte - 128) / 127 * scale_px: the displacement of the cell's content from this frame to the next in cell pixels (x right, y down; first order, v * dt); B = 0, A = 255; not sRGB";

/// Transparent pixels kept around the content when cropping, so that bilinear sampling
/// at the cells' edges reads nothing of the next cell.
pub const CROP_MARGIN_PX: u32 = 2;

/// The part of every cell of `layout` in `rgba` that shows anything: the smallest
/// rectangle `[x, y, width, height]` (cell pixels) holding every pixel with alpha > 0 in
/// any cell, grown by [`CROP_MARGIN_PX`] within the cell; with `power_of_two`, its
/// sides rounded up to powers of two (still within the cell, which is a power of two
/// itself). `None` when no cell shows anything.
pub fn content_bounds(rgba: &[u8], layout: &Layout, power_of_two: bool) -> Option<[u32; 4]> {
    let (fw, fh) = (layout.frame_width as usize, layout.frame_height as usize);
    let aw = layout.atlas_width as usize;
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for (i, px) in rgba.chunks_exact(4).enumerate() {
        if px[3] > 0 {
            let (x, y) = ((i % aw) % fw, (i / aw) % fh);
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        }
    }
    if x0 == usize::MAX {
        return None;
    }
    let m = CROP_MARGIN_PX as usize;
    let (mut x0, mut y0) = (x0.saturating_sub(m), y0.saturating_sub(m));
    let (x1, y1) = ((x1 + m).min(fw - 1), (y1 + m).min(fh - 1));
    let (mut w, mut h) = (x1 - x0 + 1, y1 - y0 + 1);
    if power_of_two {
        (w, h) = (w.next_power_of_two().min(fw), h.next_power_of_two().min(fh));
        (x0, y0) = (x0.min(fw - w), y0.min(fh - h));
    }
    Some([x0 as u32, y0 as u32, w as u32, h as u32])
}

/// The atlas `rgba` of `layout` with every cell cut to `rect` ([`content_bounds`]):
/// its bytes and layout (the same cells in the same order).
pub fn cropped(rgba: &[u8], layout: &Layout, rect: [u32; 4]) -> (Vec<u8>, Layout) {
    let [x0, y0, w, h] = rect.map(|v| v as usize);
    let (fw, fh, aw) =
        (layout.frame_width as usize, layout.frame_height as usize, layout.atlas_width as usize);
    let (columns, rows) = (layout.columns as usize, layout.rows as usize);
    let out_w = columns * w;
    let mut out = vec![0u8; out_w * rows * h * 4];
    for cy in 0..rows {
        for cx in 0..columns {
            for y in 0..h {
                let from = ((cy * fh + y0 + y) * aw + cx * fw + x0) * 4;
                let to = ((cy * h + y) * out_w + cx * w) * 4;
                out[to..to + w * 4].copy_from_slice(&rgba[from..from + w * 4]);
            }
        }
    }
    let layout = Layout {
        frame_width: w as u32,
        frame_height: h as u32,
        atlas_width: out_w as u32,
        atlas_height: (rows * h) as u32,
        ..*layout
    };
    (out, layout)
}

/// Frame `j` of the looped sequence (display-linear RGB).
pub fn looped(frames: &[Vec<f32>], j: usize, n: usize, k: usize) -> std::borrow::Cow<'_, [f32]> {
    if j >= k {
        return std::borrow::Cow::Borrowed(&frames[j]);
    }
    let w = (j + 1) as f32 / (k + 1) as f32;
    let (a, b) = (&frames[j], &frames[n + j]);
    std::borrow::Cow::Owned(a.iter().zip(b).map(|(&a, &b)| w * a + (1.0 - w) * b).collect())
}

/// One pixel as sRGB8 colour and 8-bit alpha.
fn rgba(v: &[f32], alpha: Alpha) -> [u8; 4] {
    use phenomena_core::color::srgb_encode_u8_fast;
    let c = [v[0].clamp(0.0, 1.0), v[1].clamp(0.0, 1.0), v[2].clamp(0.0, 1.0)];
    let a = c[0].max(c[1]).max(c[2]);
    let colour = match alpha {
        Alpha::Premultiplied => c,
        Alpha::Straight if a > 0.0 => c.map(|x| x / a),
        Alpha::Straight => [0.0; 3],
    };
    [
        srgb_encode_u8_fast(colour[0]),
        srgb_encode_u8_fast(colour[1]),
        srgb_encode_u8_fast(colour[2]),
        (a * 255.0).round() as u8,
    ]
}

/// The descriptor written beside the atlas.
#[derive(Clone, Debug, Serialize)]
pub struct Descriptor {
    /// The atlas image's file name.
    pub image: String,
    /// The layout.
    #[serde(flatten)]
    pub layout: Layout,
    /// Playback rate.
    pub fps: f64,
    /// Straight or premultiplied alpha.
    pub alpha: Alpha,
    /// Frames cross-faded into the first (0: not a loop).
    pub loop_frames: u32,
    /// Cell order.
    pub order: &'static str,
    /// Colour encoding of the atlas.
    pub color_space: &'static str,
    /// The scene frames the flipbook was made from, first and last + 1.
    pub source_frames: [u32; 2],
    /// With `--crop`: where the cells lie in the rendered frame, `[x, y, width,
    /// height]` pixels (of the frame as resampled to the uncropped cell size).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crop: Option<[u32; 4]>,
    /// With `--motion`: the motion atlas beside it ([`MotionAtlas`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionDescriptor>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(pot: bool, loop_frames: u32) -> FlipbookOptions {
        FlipbookOptions {
            power_of_two: pot,
            alpha: Alpha::Straight,
            loop_frames,
            crop: false,
            motion: false,
            fps: 60.0,
        }
    }

    /// Motion vectors go to the colour's cells: decoded, each pixel is its vector to
    /// within half an 8-bit code, still is 128, the largest component sets the scale, and
    /// a looped head cell is the colour's cross-fade of its vectors.
    #[test]
    fn motion_cells_decode_to_their_vectors() {
        let l = layout(5, 3, 2, &opts(false, 1)).unwrap();
        let mut m = MotionAtlas::new(l, 1);
        let frame = |j: usize| -> Vec<[f32; 2]> {
            (0..6).map(|i| [j as f32 - 2.0 + 0.2371 * i as f32, -(i as f32) * 0.4993]).collect()
        };
        for j in 0..5 {
            m.push(frame(j)).unwrap();
        }
        assert!(m.push(frame(5)).is_err(), "a sixth frame");
        let (rgba, scale) = m.finish().unwrap();
        // The largest component: 5 × 0.4993 = 2.4965 px down (frame 3's 1 + 5 × 0.2371
        // = 2.19 px across is less), to a step of 1/(32767 / 3) px.
        let step = 3.0 / 32767.0;
        assert!((scale - 2.4965).abs() <= step, "scale {scale}");
        let decode = |v: u8| (f32::from(v) - 128.0) / 127.0 * scale;
        // Still is 128 exactly.
        let mut still = MotionAtlas::new(l, 1);
        for _ in 0..5 {
            still.push(vec![[0.0, 0.0]; 6]).unwrap();
        }
        assert!(still.finish().unwrap().0.chunks(4).all(|p| p == [128, 128, 0, 255]));
        let want = |j: usize, i: usize| -> [f32; 2] {
            if j == 0 {
                // Head 0 faded with tail 4 at w = 1/2.
                let (a, b) = (frame(0)[i], frame(4)[i]);
                [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])]
            } else {
                frame(j)[i]
            }
        };
        for j in 0..4 {
            let (cx, cy) = (j % l.columns as usize * 3, j / l.columns as usize * 2);
            for i in 0..6 {
                let at = ((cy + i / 3) * l.atlas_width as usize + cx + i % 3) * 4;
                let got = [decode(rgba[at]), decode(rgba[at + 1])];
                let w = want(j, i);
                // Half an 8-bit code (scale / 254) and the stored step's rounding.
                let tolerance = scale / 254.0 + step;
                assert!(
                    (got[0] - w[0]).abs() <= tolerance && (got[1] - w[1]).abs() <= tolerance,
                    "cell {j} pixel {i}: {got:?} {w:?}"
                );
                assert_eq!((rgba[at + 2], rgba[at + 3]), (0, 255));
            }
        }
    }

    /// Cropping keeps every lit pixel of every cell (at its place in the cell, less the
    /// crop's corner) and the margin, and nothing else; power-of-two crops stay powers
    /// of two inside the cell; an atlas showing nothing is not cropped.
    #[test]
    fn crops_keep_every_lit_pixel_and_the_margin() {
        let (w, h) = (40u32, 24u32);
        // Three frames, each lit at one spot: the union spans x 10..=25, y 5..=14.
        let spots = [(10usize, 5usize), (25, 9), (18, 14)];
        let frames: Vec<Vec<f32>> = spots
            .iter()
            .map(|&(sx, sy)| {
                let mut f = vec![0.0f32; (w * h * 3) as usize];
                f[(sy * w as usize + sx) * 3] = 0.5;
                f
            })
            .collect();
        let l = layout(3, w, h, &opts(false, 0)).unwrap();
        let rgba = atlas(&frames, &l, &opts(false, 0)).unwrap();
        let m = CROP_MARGIN_PX;
        let rect = content_bounds(&rgba, &l, false).unwrap();
        assert_eq!(rect, [10 - m, 5 - m, 16 + 2 * m, 10 + 2 * m]);
        let (out, cl) = cropped(&rgba, &l, rect);
        assert_eq!((cl.frame_width, cl.frame_height, cl.columns, cl.rows), (20, 14, l.columns, l.rows));
        assert_eq!(out.len(), (cl.atlas_width * cl.atlas_height * 4) as usize);
        let lit: Vec<(u32, u32, u32)> = out
            .chunks_exact(4)
            .enumerate()
            .filter(|(_, p)| p[3] > 0)
            .map(|(i, _)| {
                let (x, y) = (i as u32 % cl.atlas_width, i as u32 / cl.atlas_width);
                let cell = (y / cl.frame_height) * cl.columns + x / cl.frame_width;
                (cell, x % cl.frame_width + rect[0], y % cl.frame_height + rect[1])
            })
            .collect();
        let want: Vec<(u32, u32, u32)> =
            spots.iter().enumerate().map(|(k, &(x, y))| (k as u32, x as u32, y as u32)).collect();
        let mut lit = lit;
        lit.sort();
        assert_eq!(lit, want);
        // Powers of two (the 40x24 frames are resampled to 32x32 cells): the crop's sides
        // are powers of two and it stays inside the cell.
        let lp = layout(3, w, h, &opts(true, 0)).unwrap();
        let small: Vec<Vec<f32>> = (0..3)
            .map(|k| {
                let mut f = vec![0.0f32; (lp.frame_width * lp.frame_height * 3) as usize];
                f[(4 * lp.frame_width as usize + 3 + 9 * k) * 3 + 1] = 0.7;
                f
            })
            .collect();
        let rgba = atlas(&small, &lp, &opts(true, 0)).unwrap();
        let r = content_bounds(&rgba, &lp, true).unwrap();
        assert!(r[2].is_power_of_two() && r[3].is_power_of_two(), "{r:?}");
        assert!(r[0] + r[2] <= lp.frame_width && r[1] + r[3] <= lp.frame_height, "{r:?} in {lp:?}");
        // Nothing lit: nothing to crop to.
        let dark = vec![vec![0.0f32; (w * h * 3) as usize]; 3];
        assert_eq!(content_bounds(&atlas(&dark, &l, &opts(false, 0)).unwrap(), &l, false), None);
    }

    #[test]
    fn layouts() {
        let l = layout(10, 100, 60, &opts(false, 0)).unwrap();
        assert_eq!((l.columns, l.rows, l.atlas_width, l.atlas_height), (4, 3, 400, 180));
        let l = layout(10, 100, 60, &opts(true, 0)).unwrap();
        assert_eq!((l.columns, l.rows, l.frame_width, l.frame_height), (4, 4, 128, 64));
        assert!(l.atlas_width.is_power_of_two() && l.atlas_height.is_power_of_two());
        let l = layout(20, 64, 64, &opts(false, 4)).unwrap();
        assert_eq!(l.frames, 16);
        assert!(layout(20, 64, 64, &opts(false, 11)).unwrap_err().contains("--loop 11"));
        assert!(layout(400, 4096, 4096, &opts(false, 0)).unwrap_err().contains("over 16384"));
        assert_eq!(nearest_power_of_two(1), 1);
        assert_eq!(nearest_power_of_two(180), 128);
        assert_eq!(nearest_power_of_two(182), 256);
    }

    #[test]
    fn alpha_modes_give_back_the_frame_over_black() {
        let v = [0.5f32, 0.25, 0.1];
        let s = rgba(&v, Alpha::Straight);
        let p = rgba(&v, Alpha::Premultiplied);
        assert_eq!(s[3], 128);
        assert_eq!(s[0], 255);
        assert_eq!(p[..3], [188, 137, 89]);
        assert_eq!(rgba(&[0.0; 3], Alpha::Straight), [0, 0, 0, 0]);
    }

    /// The whole atlas made directly from every frame (each cell from [`looped`]), as
    /// it was before [`Atlas`] built it a frame at a time.
    fn atlas_of_all_frames(frames: &[Vec<f32>], layout: &Layout, options: &FlipbookOptions) -> Vec<u8> {
        let (k, n) = (options.loop_frames as usize, layout.frames as usize);
        let (fw, fh, aw) =
            (layout.frame_width as usize, layout.frame_height as usize, layout.atlas_width as usize);
        let mut out = vec![0u8; aw * layout.atlas_height as usize * 4];
        for j in 0..n {
            let cell = looped(frames, j, n, k);
            let (cx, cy) = (j % layout.columns as usize, j / layout.columns as usize);
            for y in 0..fh {
                for x in 0..fw {
                    let at = ((cy * fh + y) * aw + cx * fw + x) * 4;
                    out[at..at + 4].copy_from_slice(&rgba(&cell[(y * fw + x) * 3..][..3], options.alpha));
                }
            }
        }
        out
    }

    /// Building the atlas a frame at a time gives the bytes of building it from every
    /// frame at once, with and without a loop, in both alpha modes.
    #[test]
    fn the_atlas_built_frame_by_frame_equals_the_whole() {
        for (rendered, k, alpha) in
            [(7, 0, Alpha::Straight), (12, 3, Alpha::Premultiplied), (10, 5, Alpha::Straight)]
        {
            let options = FlipbookOptions {
                power_of_two: false,
                alpha,
                loop_frames: k,
                crop: false,
                motion: false,
                fps: 30.0,
            };
            let l = layout(rendered, 5, 3, &options).unwrap();
            let frames: Vec<Vec<f32>> = (0..rendered)
                .map(|f| (0..45).map(|v| ((f * 45 + v) as f32 * 0.618).fract() * 1.2).collect())
                .collect();
            assert_eq!(atlas(&frames, &l, &options).unwrap(), atlas_of_all_frames(&frames, &l, &options));
        }
    }

    #[test]
    fn the_loop_cross_fades_the_tail_into_the_head() {
        // Frames whose value is their index: the loop's seam steps by no more than the
        // fade's own steps.
        let n = 12;
        let frames: Vec<Vec<f32>> = (0..n).map(|i| vec![i as f32 / n as f32; 3]).collect();
        let (k, m) = (4, n - 4);
        let seq: Vec<f32> = (0..m).map(|j| looped(&frames, j, m, k)[0]).collect();
        let steps: Vec<f32> = seq.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        let seam = (seq[0] - seq[m - 1]).abs();
        assert!(seam <= steps.iter().copied().fold(0.0, f32::max) + 1e-6, "seam {seam} steps {steps:?}");
        assert_eq!(seq[m - 1], frames[m - 1][0]);
    }
}
