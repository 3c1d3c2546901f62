//! Linear floating-point frame buffers, point deposit and separable Gaussian blur.
//!
//! Pixel `(i, j)` covers `[i, i+1) × [j, j+1)` in continuous pixel coordinates, so its
//! centre is `(i + 0.5, j + 0.5)`; `j` grows downwards. Buffers are planar (one `Vec<f32>`
//! per channel): splat loops then touch contiguous memory and vectorise.
//!
//! ```
//! use phenomena_core::image::Plane;
//! let mut p = Plane::new(9, 9);
//! p.deposit_nearest(4.5, 4.5, 1.0);
//! p.gaussian_blur(1.0);
//! assert!((p.sum() - 1.0).abs() < 1e-6); // energy is kept away from the border
//! assert!(p.get(4, 4) > p.get(5, 4));
//! ```

use glam::Vec3;
use rayon::prelude::*;

/// Five planes of one size cut into chunks of `n` samples (a band of rows: `n` a
/// multiple of the width), the chunks at the same place together as one item, in
/// parallel and in order (the five line images of the aurora, the flame's colour and
/// offsets).
pub fn par_chunks5(
    planes: &mut [Plane; 5],
    n: usize,
) -> impl IndexedParallelIterator<Item = [&mut [f32]; 5]> {
    let [p0, p1, p2, p3, p4] = planes;
    p0.data
        .par_chunks_mut(n)
        .zip(p1.data.par_chunks_mut(n))
        .zip(p2.data.par_chunks_mut(n))
        .zip(p3.data.par_chunks_mut(n))
        .zip(p4.data.par_chunks_mut(n))
        .map(|((((a, b), c), d), e)| [a, b, c, d, e])
}

/// One channel of `width × height` linear f32 samples, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl Plane {
    /// A zeroed plane.
    pub fn new(width: usize, height: usize) -> Self {
        Self { width, height, data: vec![0.0; width * height] }
    }

    /// A plane from row-major samples; `None` if the length does not match.
    pub fn from_vec(width: usize, height: usize, data: Vec<f32>) -> Option<Self> {
        (data.len() == width * height).then_some(Self { width, height, data })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row-major samples.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Mutable row-major samples.
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// Sample at pixel `(x, y)`; panics if out of range (an internal invariant).
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Set pixel `(x, y)`.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: f32) {
        self.data[y * self.width + x] = v;
    }

    /// Set every sample to zero.
    pub fn clear(&mut self) {
        self.data.fill(0.0);
    }

    /// Sum of all samples (in f64, sequentially, so it is deterministic).
    pub fn sum(&self) -> f64 {
        self.data.iter().map(|&v| f64::from(v)).sum()
    }

    /// Add `value` to the pixel containing continuous position `(x, y)`; ignored outside.
    #[inline]
    pub fn deposit_nearest(&mut self, x: f32, y: f32, value: f32) {
        if x >= 0.0 && y >= 0.0 {
            let (i, j) = (x as usize, y as usize);
            if i < self.width && j < self.height {
                self.data[j * self.width + i] += value;
            }
        }
    }

    /// Share `value` among the four pixels around `(x, y)` with bilinear weights (cloud-
    /// in-cell); the parts falling outside the plane are dropped.
    pub fn deposit_bilinear(&mut self, x: f32, y: f32, value: f32) {
        let (fx, fy) = (x - 0.5, y - 0.5);
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        for (dy, wy) in [(0, 1.0 - ty), (1, ty)] {
            for (dx, wx) in [(0, 1.0 - tx), (1, tx)] {
                let (i, j) = (x0 as i64 + dx, y0 as i64 + dy);
                if i >= 0 && j >= 0 && (i as usize) < self.width && (j as usize) < self.height {
                    self.data[j as usize * self.width + i as usize] += value * wx * wy;
                }
            }
        }
    }

    /// Bilinear sample at continuous position `(x, y)`, clamped to the edge pixels.
    #[inline]
    pub fn sample_bilinear(&self, x: f32, y: f32) -> f32 {
        if self.data.is_empty() {
            return 0.0;
        }
        let fx = (x - 0.5).clamp(0.0, (self.width - 1) as f32);
        let fy = (y - 0.5).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (fx as usize, fy as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
        let a = self.get(x0, y0) + (self.get(x1, y0) - self.get(x0, y0)) * tx;
        let b = self.get(x0, y1) + (self.get(x1, y1) - self.get(x0, y1)) * tx;
        a + (b - a) * ty
    }

    /// Separable Gaussian blur with standard deviation `sigma_px`, zero outside the
    /// plane (what falls off the edge is lost, as for a splat near the edge).
    ///
    /// Uses [`gaussian_weights`]. Each output sample is the sum of its taps in a fixed
    /// order (tap 0 first), whatever the thread count; the loops run over whole rows so
    /// they vectorise (no transposes).
    pub fn gaussian_blur(&mut self, sigma_px: f32) {
        self.gaussian_blur_with(sigma_px, &mut Vec::new());
    }

    /// [`Plane::gaussian_blur`] with the intermediate image in `tmp` (any contents;
    /// kept between calls so that repeated blurs allocate nothing). The same result.
    pub fn gaussian_blur_with(&mut self, sigma_px: f32, tmp: &mut Vec<f32>) {
        let weights = gaussian_weights(sigma_px);
        if weights.len() <= 1 || self.data.is_empty() {
            return;
        }
        let r = weights.len() / 2;
        let (w, h) = (self.width, self.height);
        // Horizontal pass: out[x] += w_k · row[x + k - r] for every tap k in order.
        tmp.clear();
        tmp.resize(w * h, 0.0);
        tmp.par_chunks_mut(w).zip(self.data.par_chunks(w)).for_each(|(out, row)| {
            for (k, &wk) in weights.iter().enumerate() {
                // Output x reads x + k - r: valid for x in [r - k, w + r - k) ∩ [0, w).
                let lo = r.saturating_sub(k).min(w);
                let hi = (w + r).saturating_sub(k).min(w);
                if lo >= hi {
                    continue;
                }
                let src = &row[lo + k - r..hi + k - r];
                for (o, s) in out[lo..hi].iter_mut().zip(src) {
                    *o += wk * s;
                }
            }
        });
        // Vertical pass: output row y sums rows y + k - r in tap order.
        self.data.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
            out.fill(0.0);
            for (k, &wk) in weights.iter().enumerate() {
                let Some(yy) = (y + k).checked_sub(r).filter(|&yy| yy < h) else {
                    continue;
                };
                for (o, s) in out.iter_mut().zip(&tmp[yy * w..(yy + 1) * w]) {
                    *o += wk * s;
                }
            }
        });
    }
}

/// The discrete 1-D Gaussian used by [`Plane::gaussian_blur`]: samples of
/// exp(-k²/2σ²) for |k| ≤ ceil(4σ), normalised to sum to 1 (the tail past 4σ is 6e-5 of
/// the mass). A non-positive or non-finite σ gives the identity `[1.0]`.
pub fn gaussian_weights(sigma_px: f32) -> Vec<f32> {
    if !(sigma_px > 0.0) || !sigma_px.is_finite() {
        return vec![1.0];
    }
    let r = (4.0 * sigma_px).ceil() as i64;
    let w: Vec<f64> =
        (-r..=r).map(|k| (-(k * k) as f64 / (2.0 * f64::from(sigma_px).powi(2))).exp()).collect();
    let s: f64 = w.iter().sum();
    w.iter().map(|v| (v / s) as f32).collect()
}

/// Three planes of equal size: linear RGB, or CIE XYZ where a renderer says so.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// First channel (R or X).
    pub c0: Plane,
    /// Second channel (G or Y).
    pub c1: Plane,
    /// Third channel (B or Z).
    pub c2: Plane,
}

impl Frame {
    /// A black frame.
    pub fn new(width: usize, height: usize) -> Self {
        Self { c0: Plane::new(width, height), c1: Plane::new(width, height), c2: Plane::new(width, height) }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.c0.width()
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.c0.height()
    }

    /// The three channel values at pixel `(x, y)`.
    #[inline]
    pub fn pixel(&self, x: usize, y: usize) -> Vec3 {
        Vec3::new(self.c0.get(x, y), self.c1.get(x, y), self.c2.get(x, y))
    }

    /// Set pixel `(x, y)`.
    #[inline]
    pub fn set_pixel(&mut self, x: usize, y: usize, v: Vec3) {
        self.c0.set(x, y, v.x);
        self.c1.set(x, y, v.y);
        self.c2.set(x, y, v.z);
    }

    /// Bilinear sample of all three channels at continuous position `(x, y)`, clamped
    /// to the edge pixels (the same result as [`Plane::sample_bilinear`] per channel).
    #[inline]
    pub fn sample_bilinear(&self, x: f32, y: f32) -> Vec3 {
        let (w, h) = (self.width(), self.height());
        if w == 0 || h == 0 {
            return Vec3::ZERO;
        }
        let fx = (x - 0.5).clamp(0.0, (w - 1) as f32);
        let fy = (y - 0.5).clamp(0.0, (h - 1) as f32);
        let (x0, y0) = (fx as usize, fy as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
        let (i00, i01, i10, i11) = (y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1);
        let tap = |p: &Plane| {
            let d = &p.data;
            let a = d[i00] + (d[i01] - d[i00]) * tx;
            let b = d[i10] + (d[i11] - d[i10]) * tx;
            a + (b - a) * ty
        };
        Vec3::new(tap(&self.c0), tap(&self.c1), tap(&self.c2))
    }

    /// The planes, mutably, for per-channel work.
    pub fn planes_mut(&mut self) -> [&mut Plane; 3] {
        [&mut self.c0, &mut self.c1, &mut self.c2]
    }

    /// Set every pixel (x, y) to `f(x, y, its value)`, rows in parallel (each pixel on
    /// its own: the same frame for any thread count).
    fn update_pixels(&mut self, f: impl Fn(usize, usize, Vec3) -> Vec3 + Sync) {
        self.par_bands(1, |y, [a, b, c]| {
            for x in 0..a.len() {
                let v = f(x, y, Vec3::new(a[x], b[x], c[x]));
                (a[x], b[x], c[x]) = (v.x, v.y, v.z);
            }
        });
    }

    /// `f(first row, [c0, c1, c2])` for each band of `rows` rows (the last may hold
    /// fewer), the bands in parallel, each channel's band row-major (pixel (x, y) at
    /// `(y − first row) · width + x`). Work that touches only its band's pixels gives
    /// the same frame for any thread count.
    pub fn par_bands(&mut self, rows: usize, f: impl Fn(usize, [&mut [f32]; 3]) + Sync) {
        let rows = rows.max(1);
        let n = self.width().max(1).saturating_mul(rows);
        self.c0
            .data
            .par_chunks_mut(n)
            .zip(self.c1.data.par_chunks_mut(n))
            .zip(self.c2.data.par_chunks_mut(n))
            .enumerate()
            .for_each(|(band, ((a, b), c))| f(band * rows, [a, b, c]));
    }

    /// Set every pixel (x, y) to `f(x, y)`, rows in parallel.
    pub fn fill_with(&mut self, f: impl Fn(usize, usize) -> Vec3 + Sync) {
        self.update_pixels(|x, y, _| f(x, y));
    }

    /// Apply a colour matrix to every pixel, e.g. XYZ to linear sRGB.
    pub fn map_pixels(&mut self, f: impl Fn(Vec3) -> Vec3 + Sync) {
        self.update_pixels(|_, _, v| f(v));
    }

    /// Convert an XYZ frame to linear sRGB in place (flame paper eq 17).
    pub fn xyz_to_linear_srgb(&mut self) {
        self.map_pixels(|v| crate::color::xyz_to_linear_srgb(v.as_dvec3()).as_vec3());
    }

    /// Decode 8-bit sRGB-encoded RGB bytes (row-major triples) into a linear frame, e.g.
    /// a user's background image. `None` if the length is not `width × height × 3`.
    pub fn from_srgb8(width: usize, height: usize, rgb: &[u8]) -> Option<Self> {
        if width.checked_mul(height).and_then(|n| n.checked_mul(3)) != Some(rgb.len()) {
            return None;
        }
        let decode: [f32; 256] = std::array::from_fn(|v| crate::color::srgb_decode(v as f32 / 255.0));
        let mut f = Frame::new(width, height);
        for (i, px) in rgb.chunks_exact(3).enumerate() {
            f.c0.data[i] = decode[usize::from(px[0])];
            f.c1.data[i] = decode[usize::from(px[1])];
            f.c2.data[i] = decode[usize::from(px[2])];
        }
        Some(f)
    }

    /// This frame stretched to `width × height` by bilinear sampling at the new pixel
    /// centres (clamped at the edges); at the same size, an exact copy. The one rule
    /// for image backgrounds of every phenomenon: scaled to the frame, aspect not kept.
    pub fn resized(&self, width: usize, height: usize) -> Frame {
        if (width, height) == (self.width(), self.height()) {
            return self.clone();
        }
        let mut f = Frame::new(width, height);
        if self.width() == 0 || self.height() == 0 {
            return f;
        }
        let (sx, sy) = (self.width() as f32 / width as f32, self.height() as f32 / height as f32);
        for y in 0..height {
            for x in 0..width {
                let (u, v) = ((x as f32 + 0.5) * sx, (y as f32 + 0.5) * sy);
                f.set_pixel(x, y, self.sample_bilinear(u, v));
            }
        }
        f
    }

    /// Interleaved RGB triples, row-major (for encoders).
    pub fn to_interleaved(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(self.width() * self.height() * 3);
        for i in 0..self.c0.data.len() {
            out.extend([self.c0.data[i], self.c1.data[i], self.c2.data[i]]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_cover_each_pixel_once_with_their_first_row() {
        // 7 × 11 in bands of 1, 4 (the last of 3 rows), 11 and 20 rows: each pixel is
        // written once, where its band's first row says it lies.
        for rows in [1, 4, 11, 20] {
            let mut f = Frame::new(7, 11);
            f.par_bands(rows, |row0, [a, b, c]| {
                assert_eq!(row0 % rows, 0);
                assert!(a.len() == b.len() && b.len() == c.len() && a.len() <= 7 * rows);
                for (i, ((a, b), c)) in a.iter_mut().zip(b.iter_mut()).zip(c.iter_mut()).enumerate() {
                    let (x, y) = (i % 7, row0 + i / 7);
                    (*a, *b, *c) = (*a + x as f32, *b + y as f32, *c + 1.0);
                }
            });
            for y in 0..11 {
                for x in 0..7 {
                    assert_eq!(f.pixel(x, y), Vec3::new(x as f32, y as f32, 1.0), "{rows} rows, ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn a_filled_frame_holds_each_pixels_value() {
        for (w, h) in [(1, 1), (7, 3), (64, 65)] {
            let mut f = Frame::new(w, h);
            f.fill_with(|x, y| Vec3::new(x as f32, y as f32, (x * 1000 + y) as f32));
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(
                        f.pixel(x, y),
                        Vec3::new(x as f32, y as f32, (x * 1000 + y) as f32),
                        "({x}, {y})"
                    );
                }
            }
        }
    }

    #[test]
    fn srgb_bytes_decode_and_resize_keeps_flat_colour() {
        assert!(Frame::from_srgb8(2, 2, &[0; 11]).is_none());
        let f = Frame::from_srgb8(2, 1, &[255, 0, 188, 0, 255, 0]).unwrap();
        assert_eq!(f.pixel(0, 0).x, 1.0);
        assert_eq!(f.pixel(0, 0).y, 0.0);
        // sRGB 188/255 is about 0.5 linear (IEC 61966-2-1).
        assert!((f.pixel(0, 0).z - 0.5).abs() < 0.01, "{}", f.pixel(0, 0).z);
        assert_eq!(f.resized(2, 1), f, "same size: an exact copy");
        let mut flat = Frame::new(3, 2);
        flat.map_pixels(|_| Vec3::new(0.25, 0.5, 0.75));
        let big = flat.resized(7, 5);
        assert_eq!((big.width(), big.height()), (7, 5));
        // Bilinear weights sum to one: a flat image stays flat (to rounding).
        for y in 0..5 {
            for x in 0..7 {
                assert!((big.pixel(x, y) - Vec3::new(0.25, 0.5, 0.75)).abs().max_element() < 1e-6);
            }
        }
    }

    #[test]
    fn blur_of_a_delta_is_the_sampled_gaussian() {
        let sigma = 2.0;
        let g = gaussian_weights(sigma);
        let r = g.len() / 2;
        let mut p = Plane::new(41, 41);
        p.set(20, 20, 1.0);
        p.gaussian_blur(sigma);
        for y in 0..41 {
            for x in 0..41 {
                let (dx, dy) = (x as i64 - 20, y as i64 - 20);
                let expect = if dx.unsigned_abs() as usize <= r && dy.unsigned_abs() as usize <= r {
                    g[(dx + r as i64) as usize] * g[(dy + r as i64) as usize]
                } else {
                    0.0
                };
                assert!((p.get(x, y) - expect).abs() < 1e-7, "({x},{y})");
            }
        }
        assert!((p.sum() - 1.0).abs() < 1e-5);
    }

    /// The blur as first written: per output sample, its taps summed in order from 0.0
    /// (transposing for the vertical pass).
    fn reference_blur(p: &Plane, sigma: f32) -> Vec<f32> {
        let weights = gaussian_weights(sigma);
        let r = weights.len() / 2;
        let (w, h) = (p.width(), p.height());
        let line = |src: &[f32], i: usize| {
            let n = src.len();
            let (k0, k1) = (r.saturating_sub(i), (n + r - i).min(weights.len()));
            let mut acc = 0.0f32;
            for k in k0..k1 {
                acc += weights[k] * src[i + k - r];
            }
            acc
        };
        let mut tmp = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                tmp[y * w + x] = line(&p.data()[y * w..(y + 1) * w], x);
            }
        }
        let mut out = vec![0.0f32; w * h];
        for x in 0..w {
            let col: Vec<f32> = (0..h).map(|y| tmp[y * w + x]).collect();
            for y in 0..h {
                out[y * w + x] = line(&col, y);
            }
        }
        out
    }

    #[test]
    fn row_wise_blur_is_bit_identical_to_the_per_sample_sums() {
        // Same additions in the same order: equal bits, also for planes narrower than
        // the kernel.
        for (w, h, sigma) in [(37, 23, 1.3f32), (5, 40, 2.5), (64, 3, 0.7), (1, 1, 3.0)] {
            let data: Vec<f32> = (0..w * h).map(|i| ((i * 7919) % 101) as f32 * 0.37 - 3.0).collect();
            let mut p = Plane::from_vec(w, h, data).unwrap();
            let expected = reference_blur(&p, sigma);
            p.gaussian_blur(sigma);
            assert!(
                p.data().iter().zip(&expected).all(|(a, b)| a.to_bits() == b.to_bits()),
                "{w}×{h} σ {sigma}"
            );
        }
    }

    #[test]
    fn blur_is_linear_and_thread_count_independent() {
        let mut p = Plane::new(64, 48);
        for i in 0..200 {
            let f = i as f32;
            p.deposit_bilinear((f * 7.31) % 64.0, (f * 3.77) % 48.0, 1.0 + (f * 0.1).sin());
        }
        let mut a = p.clone();
        a.gaussian_blur(1.7);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let mut b = p.clone();
        pool.install(|| b.gaussian_blur(1.7));
        assert_eq!(a, b);
    }

    #[test]
    fn bilinear_deposit_conserves_and_samples_back() {
        let mut p = Plane::new(8, 8);
        p.deposit_bilinear(3.2, 4.9, 2.0);
        assert!((p.sum() - 2.0).abs() < 1e-6);
        let mut q = Plane::new(4, 4);
        for y in 0..4 {
            for x in 0..4 {
                q.set(x, y, x as f32 + 10.0 * y as f32);
            }
        }
        // Bilinear interpolation reproduces a linear function exactly inside.
        assert!((q.sample_bilinear(1.75, 2.25) - (1.25 + 17.5)).abs() < 1e-5);
        // Clamped outside.
        assert_eq!(q.sample_bilinear(-10.0, -10.0), 0.0);
        let f = Frame { c0: q.clone(), c1: q.clone(), c2: q.clone() };
        for (x, y) in [(1.75, 2.25), (-3.0, 0.2), (9.0, 9.0), (0.5, 3.99)] {
            assert_eq!(f.sample_bilinear(x, y), Vec3::splat(q.sample_bilinear(x, y)));
        }
    }

    #[test]
    fn weights_degenerate_sigma() {
        assert_eq!(gaussian_weights(0.0), vec![1.0]);
        assert_eq!(gaussian_weights(f32::NAN), vec![1.0]);
        let g = gaussian_weights(0.3);
        assert!((g.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    }
}
