//! Glints over a background, in linear HDR RGB.
//!
//! Each seen facet is a glint of brightness k_s I_l (N·H)^n (§2) times the light's
//! colour, deposited bilinearly at its projected position (a facet is far smaller than a
//! pixel), with an optional cross or star of glare for the bright ones. The background is
//! a sky gradient with the sun's disc, a shaded crown for leaf glitter (§3.2: glitter is
//! drawn over the tree's ordinary shading), or the user's image.

use glam::Vec3;
use phenomena_core::camera::{CameraView, NEAR_M, Pinhole};
use wide::{f32x8, i32x8, u32x8};

use crate::batch::{LANES, V8};
use phenomena_core::bands::Filed;
use phenomena_core::image::Frame;
use phenomena_core::phenomenon::{RenderError, check_size, image_background};
use phenomena_core::validate::{InvalidConfig, Issue, Issues};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::{LightAt, Population};
use crate::sim::SparkleSim;

/// Longest glare ray drawn, pixels (`glare_length_px` is at most 256).
const MAX_RAY_PX: usize = 257;

/// Rows per band of the parallel splat.
pub(crate) const BAND_ROWS: usize = 32;
const _: () = assert!(BAND_ROWS.is_power_of_two(), "bands are found by a shift");

/// What lies behind the glints.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Background {
    /// A sky gradient, the sun's disc, a ground; the crown for leaf glitter.
    #[default]
    Sky,
    /// Black (glints alone, for compositing).
    Black,
    /// An image file (sRGB, stretched bilinearly to the frame's size); the caller loads
    /// it and passes it to [`SparkleRenderer::new`].
    Image {
        /// Path, relative to the scene file.
        path: std::path::PathBuf,
    },
}

/// Glare drawn around bright glints.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GlareShape {
    /// None.
    None,
    /// Four rays (a cross).
    #[default]
    Cross,
    /// Six rays (a star).
    Star,
    /// A lens (an extension): each glint's light spread as a camera lens spreads a point
    /// of light: over a defocus disc (`aperture_f_number`, `focus_m`) and, for bright
    /// glints, a round bloom of `glare_length_px` · √(I / k_s I_l), so a glint's size
    /// follows its brightness and its distance from the plane of focus.
    Lens,
}

impl GlareShape {
    /// Unit directions of the rays, in pixels (y down).
    fn rays(self) -> &'static [(f32, f32)] {
        match self {
            GlareShape::None | GlareShape::Lens => &[],
            GlareShape::Cross => &[(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)],
            GlareShape::Star => &[
                (1.0, 0.0),
                (0.5, 0.866_025_4),
                (-0.5, 0.866_025_4),
                (-1.0, 0.0),
                (-0.5, -0.866_025_4),
                (0.5, -0.866_025_4),
            ],
        }
    }
}

/// The `[render]` table of a sparkle scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSettings {
    /// Background.
    pub background: Background,
    /// Radiance added to a pixel per unit of glint brightness.
    pub glint_gain: f32,
    /// Light colour, linear RGB (multiplies every glint).
    pub light_rgb: [f32; 3],
    /// Glare shape.
    pub glare: GlareShape,
    /// Length of the glare rays of the brightest glint, pixels (scaled by √brightness).
    pub glare_length_px: f32,
    /// Glare brightness relative to the glint's.
    pub glare_strength: f32,
    /// Glints dimmer than this fraction of k_s I_l get no glare.
    pub glare_threshold: f32,
    /// Sky at the zenith, linear RGB.
    pub sky_zenith_rgb: [f32; 3],
    /// Sky at the horizon, linear RGB.
    pub sky_horizon_rgb: [f32; 3],
    /// Ground, linear RGB (lit by the sun for leaf glitter).
    pub ground_rgb: [f32; 3],
    /// Crown albedo for leaf glitter, linear RGB.
    pub crown_rgb: [f32; 3],
    /// An extension (the paper has none): glints farther than this from the camera dim
    /// as (distance / this)⁻², as the light a point reflector sends to the eye does;
    /// 0 keeps the paper's distance-independent brightness. Metres. The default, 8 m,
    /// is for the default 100 m box of diamond dust: with 0 its 10⁹ crystals pile up into
    /// a white band at the horizon whose width depends on the image's resolution.
    pub falloff_from_m: f32,
    /// With `glare = "lens"`: the aperture's f-number on a 35 mm full-frame camera
    /// (sensor 24 mm high, the focal length the field of view gives); 0: a pinhole, no
    /// defocus.
    pub aperture_f_number: f32,
    /// With `glare = "lens"`: the distance in focus, metres.
    pub focus_m: f32,
    /// An extension (0: off, the paper's constant k_s): the facets' refractive index
    /// (ice: 1.31); each glint is weighted by its Fresnel reflectance at its angle of
    /// incidence relative to normal incidence (Schlick), so facets that mirror the sun
    /// at grazing incidence (seen towards the sun) outshine those seen with the sun
    /// behind the eye, up to 1 / F0 = 56 times for ice.
    pub fresnel_ior: f32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            background: Background::Sky,
            glint_gain: 4.0,
            light_rgb: [1.0, 0.97, 0.92],
            glare: GlareShape::Cross,
            glare_length_px: 9.0,
            glare_strength: 0.35,
            glare_threshold: 0.5,
            sky_zenith_rgb: [0.06, 0.12, 0.30],
            sky_horizon_rgb: [0.45, 0.55, 0.70],
            ground_rgb: [0.55, 0.58, 0.62],
            crown_rgb: [0.05, 0.16, 0.04],
            falloff_from_m: 8.0,
            aperture_f_number: 0.0,
            focus_m: 10.0,
            fresnel_ior: 0.0,
        }
    }
}

impl RenderSettings {
    /// Every problem with the field, value and valid range.
    pub fn validate(&self) -> Result<(), Vec<Issue>> {
        let mut i = Issues::default();
        i.range("glint_gain", self.glint_gain, 0.0..=1e9);
        i.range("glare_length_px", self.glare_length_px, 0.0..=256.0);
        i.range("glare_strength", self.glare_strength, 0.0..=100.0);
        i.range("glare_threshold", self.glare_threshold, 0.0..=1.0);
        i.range("falloff_from_m", self.falloff_from_m, 0.0..=1e6);
        if self.aperture_f_number != 0.0 {
            i.range("aperture_f_number", self.aperture_f_number, 0.5..=64.0);
        }
        i.range_open_low("focus_m", self.focus_m, 0.0, 1e6);
        if self.fresnel_ior != 0.0 {
            i.range("fresnel_ior", self.fresnel_ior, 1.01..=4.0);
        }
        for (name, v) in [
            ("light_rgb", self.light_rgb),
            ("sky_zenith_rgb", self.sky_zenith_rgb),
            ("sky_horizon_rgb", self.sky_horizon_rgb),
            ("ground_rgb", self.ground_rgb),
            ("crown_rgb", self.crown_rgb),
        ] {
            if v.iter().any(|c| !(c.is_finite() && *c >= 0.0 && *c <= 1e6)) {
                i.push(name, format!("{v:?}"), "three finite values in [0, 1e6]");
            }
        }
        i.into_result()
    }
}

/// Renders a [`SparkleSim`] frame by frame into linear RGB.
#[derive(Clone, Debug)]
pub struct SparkleRenderer {
    settings: RenderSettings,
    user_background: Option<Frame>,
    /// Background and the light it was drawn for (redrawn when the sun moves).
    cached: Option<(LightAt, Frame)>,
    frame: Frame,
}

impl SparkleRenderer {
    /// Whether [`SparkleRenderer::new`] accepts `settings` at `width × height` (besides
    /// the background image), without allocating any image.
    pub fn check(settings: &RenderSettings, width: usize, height: usize) -> Result<(), RenderError> {
        settings.validate().map_err(InvalidConfig::from)?;
        check_size(width, height)
    }

    /// A renderer of `width × height` frames; `background` is the loaded image (linear
    /// RGB, any size: it is stretched to the frame by [`Frame::resized`]) when the
    /// settings ask for one.
    pub fn new(
        settings: RenderSettings,
        width: usize,
        height: usize,
        background: Option<&Frame>,
    ) -> Result<Self, RenderError> {
        Self::check(&settings, width, height)?;
        let wanted = matches!(settings.background, Background::Image { .. });
        let user_background = image_background(wanted, background, width, height)?;
        Ok(Self { settings, user_background, cached: None, frame: Frame::new(width, height) })
    }

    /// The last rendered frame.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// Render the simulation's current glints over the background.
    pub fn render(&mut self, sim: &SparkleSim) -> &Frame {
        let (w, h) = (self.frame.width(), self.frame.height());
        let Some(view) = sim.config().camera.view(w, h) else {
            self.frame = Frame::new(w, h);
            return &self.frame;
        };
        self.update_background(sim, &view);
        if let Some((_, bg)) = &self.cached {
            splat(&self.settings, &mut self.frame, bg, sim, &view, None);
        }
        &self.frame
    }

    /// Draw the background again when the light has moved since it was drawn.
    fn update_background(&mut self, sim: &SparkleSim, view: &CameraView) {
        let (w, h) = (self.frame.width(), self.frame.height());
        let light = sim.config().light.at(sim.time_s());
        let fresh = !matches!(&self.cached, Some((l, _)) if *l == light);
        if fresh {
            let bg = match (&self.settings.background, &self.user_background) {
                (Background::Image { .. }, Some(img)) => img.clone(),
                (Background::Black, _) => Frame::new(w, h),
                _ => sky(&self.settings, view, light, &sim.config().population),
            };
            self.cached = Some((light, bg));
        }
    }

    /// The background the glints are drawn over now (the sky for the light's place,
    /// the image, or black), for composition with other phenomena.
    pub fn background(&mut self, sim: &SparkleSim) -> Frame {
        let (w, h) = (self.frame.width(), self.frame.height());
        match sim.config().camera.view(w, h) {
            Some(view) => {
                self.update_background(sim, &view);
                self.cached.as_ref().map_or_else(|| Frame::new(w, h), |(_, bg)| bg.clone())
            }
            None => Frame::new(w, h),
        }
    }

    /// The glints (and glare) alone over black, only those `window` keeps, for
    /// composition with other phenomena (the settings' background is not drawn).
    pub fn render_glints(&mut self, sim: &SparkleSim, window: DepthWindow<'_>) -> &Frame {
        let (w, h) = (self.frame.width(), self.frame.height());
        let black = Frame::new(w, h);
        match sim.config().camera.view(w, h) {
            Some(view) => splat(&self.settings, &mut self.frame, &black, sim, &view, Some(window)),
            None => self.frame = black,
        }
        &self.frame
    }
}

impl phenomena_core::phenomenon::Renderer<SparkleSim> for SparkleRenderer {
    fn render(&mut self, sim: &SparkleSim) -> &Frame {
        SparkleRenderer::render(self, sim)
    }

    fn frame(&self) -> &Frame {
        SparkleRenderer::frame(self)
    }
}

/// The background plus the glints (and glare), into `frame`. Glints are projected in
/// parallel, bucketed by bands of [`BAND_ROWS`] rows that their footprint touches, and
/// each band adds its glints in glint order: every pixel sums in the same order for any
/// thread count. Each band writes its rows of the frame once (background + glints).
fn splat(
    s: &RenderSettings,
    frame: &mut Frame,
    bg: &Frame,
    sim: &SparkleSim,
    view: &CameraView,
    window: Option<DepthWindow<'_>>,
) {
    let colour = Vec3::from(s.light_rgb) * s.glint_gain;
    let (wu, hu) = (frame.width(), frame.height());
    let bands = hu.div_ceil(BAND_ROWS);
    let chunks = project_glints(s, sim, view, (wu, hu), bands, window);
    let glare = Glare::of(s);
    let [c0, c1, c2] = frame.planes_mut();
    let stride = BAND_ROWS * wu;
    let (b0, b1, b2) = (bg.c0.data(), bg.c1.data(), bg.c2.data());
    c0.data_mut()
        .par_chunks_mut(stride)
        .zip(c1.data_mut().par_chunks_mut(stride))
        .zip(c2.data_mut().par_chunks_mut(stride))
        .enumerate()
        .for_each(|(b, ((r, gr), bl))| {
            // Every glint has the light's colour: the band sums brightness in one
            // plane, coloured once at the end.
            let band = BandRows { width: wu, row0: (b * BAND_ROWS) as i64, rows: (r.len() / wu) as i64 };
            let mut sum = vec![0.0f32; r.len()];
            band.add_glints(&chunks, b, &glare, &mut sum);
            let at = b * stride;
            let (b0, b1, b2) = (&b0[at..at + r.len()], &b1[at..at + r.len()], &b2[at..at + r.len()]);
            for (k, v) in sum.iter().enumerate() {
                r[k] = b0[k] + colour.x * v;
                gr[k] = b1[k] + colour.y * v;
                bl[k] = b2[k] + colour.z * v;
            }
        });
}

/// Every glint projected to a dot on screen (brightness with the distance falloff and
/// glare length of [`RenderSettings`]) and filed by the `bands` of [`BAND_ROWS`] rows its
/// footprint touches (a dot spanning two bands in both). Chunks of [`PROJECT_CHUNK`]
/// glints are projected in parallel, each keeping glint order: a band reading its run
/// from every chunk in chunk order reads its dots in glint order.
fn project_glints(
    s: &RenderSettings,
    sim: &SparkleSim,
    view: &CameraView,
    (width_px, height_px): (usize, usize),
    bands: usize,
    window: Option<DepthWindow<'_>>,
) -> Vec<Filed<Dot>> {
    let g = sim.glints();
    let glare = !s.glare.rays().is_empty() || s.glare == GlareShape::Lens;
    let screen = Screen {
        pinhole: view.pinhole(),
        eye: sim.config().camera.position,
        falloff2: s.falloff_from_m * s.falloff_from_m,
        peak: sim.config().phong.specular_k_s * sim.config().phong.light_intensity,
        glare_length: if glare { s.glare_length_px } else { 0.0 },
        glare_threshold: s.glare_threshold,
        lens: (s.glare == GlareShape::Lens).then(|| Lens::of(s, view, height_px)).flatten(),
        size: (width_px as f32, height_px as f32),
        last_band: bands as u32 - 1,
        window,
    };
    let light = sim.config().light.at(sim.time_s());
    g.position_m
        .par_chunks(PROJECT_CHUNK)
        .zip(g.intensity.par_chunks(PROJECT_CHUNK))
        .zip(g.normal.par_chunks(PROJECT_CHUNK))
        .map(|((xs, is), ns)| {
            let mut dots = Vec::with_capacity(xs.len());
            let weighted: Vec<f32>;
            let is = if s.fresnel_ior > 0.0 {
                weighted =
                    (0..xs.len()).map(|k| is[k] * fresnel_gain(s.fresnel_ior, light, xs[k], ns[k])).collect();
                &weighted[..]
            } else {
                is
            };
            for (xc, ic) in xs.chunks(LANES).zip(is.chunks(LANES)) {
                screen.place(view, xc, ic, |d, lo, hi| dots.push((d, lo, hi)));
            }
            Filed::file(bands, dots.len(), |i| Some((dots[i].1, dots[i].2)), |i| dots[i].0)
        })
        .collect()
}

/// Length of the per-ray glare weights: [`MAX_RAY_PX`] steps in whole lanes.
const FALL_LEN: usize = MAX_RAY_PX.next_multiple_of(LANES);

/// The glare rays drawn around bright glints.
struct Glare<'a> {
    /// Unit directions of the rays, px (y down).
    rays: &'a [(f32, f32)],
    /// Whether every ray runs along a pixel axis (whole-pixel steps).
    axis_rays: bool,
    /// The directions as whole-pixel offsets (used when `axis_rays`).
    whole_rays: Vec<(i64, i64)>,
    /// Glare brightness relative to the glint's, in every lane.
    strength: f32x8,
    /// Steps 1..=8 along a ray, px.
    first_steps: f32x8,
    /// A lens's round spread instead of rays.
    lens: bool,
    /// Glare brightness relative to the glint's.
    strength_1: f32,
}

impl<'a> Glare<'a> {
    /// The glare `s` asks for.
    fn of(s: &'a RenderSettings) -> Self {
        let rays = s.glare.rays();
        Self {
            rays,
            axis_rays: rays.iter().all(|&(dx, dy)| dx.fract() == 0.0 && dy.fract() == 0.0),
            whole_rays: rays.iter().map(|&(dx, dy)| (dx as i64, dy as i64)).collect(),
            strength: f32x8::splat(s.glare_strength),
            first_steps: f32x8::from([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]),
            lens: s.glare == GlareShape::Lens,
            strength_1: s.glare_strength,
        }
    }

    /// The brightness of the ray pixels of a glint of brightness `v` and glare length
    /// `len` px, into `fall[step - 1]`: at `step` px along each ray, step = 1..=len,
    /// falling off as (1 - step/len)² (the same on every ray). Eight steps at a time;
    /// returns the number of steps within the ray (t ≤ 1), the later ones are not used.
    #[inline]
    fn falloff(&self, len: f32, v: f32, fall: &mut [f32; FALL_LEN]) -> usize {
        let steps = (len.ceil() as usize).min(MAX_RAY_PX);
        let inv = 1.0 / len;
        let (inv8, v8) = (f32x8::splat(inv), f32x8::splat(v));
        let mut n = 0;
        for (base, f) in (0..steps).step_by(LANES).zip(fall.chunks_exact_mut(LANES)) {
            let t = (self.first_steps + f32x8::splat(base as f32)) * inv8;
            let near = f32x8::ONE - t;
            f.copy_from_slice(&(v8 * near * near * self.strength * inv8).to_array());
            let within = (steps - base).min(LANES);
            n += (t.simd_le(f32x8::ONE).to_bitmask() & ((1u32 << within) - 1)).count_ones() as usize;
        }
        n
    }
}

/// The rows of the image one band of the splat covers.
#[derive(Clone, Copy)]
struct BandRows {
    /// Image width, px.
    width: usize,
    /// The band's first row.
    row0: i64,
    /// Rows in the band.
    rows: i64,
}

impl BandRows {
    /// Add `v` to pixel (i, j) of the band's sums if it lies in the band and the image.
    #[inline]
    fn add(&self, sum: &mut [f32], i: i64, j: i64, v: f32) {
        let jj = j - self.row0;
        if i >= 0 && (i as usize) < self.width && jj >= 0 && jj < self.rows {
            sum[jj as usize * self.width + i as usize] += v;
        }
    }

    /// The brightness of the dots of band `b` from every chunk (in glint order) and their
    /// glare, added to the band's pixels `sum`.
    #[inline]
    fn add_glints(&self, chunks: &[Filed<Dot>], b: usize, glare: &Glare<'_>, sum: &mut [f32]) {
        let mut fall = [0.0f32; FALL_LEN];
        for filed in chunks {
            for group in filed.band(b).chunks(LANES) {
                let four = Bilinear::of(group);
                for (k, d) in group.iter().enumerate() {
                    if four.inside & (1 << k) != 0 {
                        self.deposit(sum, &four, k);
                    }
                    if d.len == 0.0 {
                        continue;
                    }
                    if glare.lens {
                        self.add_lens(sum, d, glare.strength_1);
                        continue;
                    }
                    let n = glare.falloff(d.len, d.value, &mut fall);
                    if glare.axis_rays {
                        self.add_axis_rays(sum, d, &glare.whole_rays, &fall[..n]);
                    } else {
                        self.add_rays(sum, d, glare.rays, &fall[..n]);
                    }
                }
            }
        }
    }

    /// A lens's spread of `dot` ([`LensSpread`]), its weights scaled to their sum over
    /// the whole footprint (`dot.norm`, worked out once per glint), so the band or the
    /// image clipping it drops light but never adds any.
    fn add_lens(&self, sum: &mut [f32], dot: &Dot, strength: f32) {
        let Some(spread) = LensSpread::of(dot, strength) else { return };
        if !(dot.norm > 0.0) {
            return;
        }
        let scale = spread.total / dot.norm;
        let (xi, yi, reach) = spread.window(dot);
        let (j0, j1) = ((yi - reach).max(self.row0), (yi + reach).min(self.row0 + self.rows - 1));
        let scale8 = f32x8::splat(scale);
        for j in j0..=j1 {
            let Some((i0, i1)) = spread.span(dot, j, (xi, reach)) else { continue };
            let (i0, i1) = (i0.max(0), i1.min(self.width as i64 - 1));
            if i0 > i1 {
                continue;
            }
            // The row's pixels i0..=i1 (in the band and the image), eight at a time: each
            // pixel adds w × scale where w > 0, as one at a time would.
            let row = &mut sum[(j - self.row0) as usize * self.width..][i0 as usize..=i1 as usize];
            for (k, pixels) in row.chunks_mut(LANES).enumerate() {
                let w = spread.weight8(dot, i0 + (k * LANES) as i64, j);
                let (add, v) = (w.simd_gt(f32x8::ZERO), w * scale8);
                if let Ok(pixels) = <&mut [f32; LANES]>::try_from(&mut *pixels) {
                    let old = f32x8::from(*pixels);
                    *pixels = add.select(old + v, old).to_array();
                } else {
                    let (add, v) = (add.to_bitmask(), v.to_array());
                    for (l, p) in pixels.iter_mut().enumerate() {
                        if add & (1 << l) != 0 {
                            *p += v[l];
                        }
                    }
                }
            }
        }
    }

    /// Dot `k` of `four` deposited bilinearly on its four pixels.
    #[inline]
    fn deposit(&self, sum: &mut [f32], four: &Bilinear, k: usize) {
        let (i0, j0) = (i64::from(four.i0[k]), i64::from(four.j0[k]));
        let shares = [four.share[0][k], four.share[1][k], four.share[2][k], four.share[3][k]];
        let (wu, row0, rows) = (self.width, self.row0, self.rows);
        if i0 >= 0 && i0 + 1 < wu as i64 && j0 >= row0 && j0 + 1 < row0 + rows {
            // All four pixels in the band (most dots).
            let at = (j0 - row0) as usize * wu + i0 as usize;
            sum[at] += shares[0];
            sum[at + 1] += shares[1];
            sum[at + wu] += shares[2];
            sum[at + wu + 1] += shares[3];
        } else {
            self.add(sum, i0, j0, shares[0]);
            self.add(sum, i0 + 1, j0, shares[1]);
            self.add(sum, i0, j0 + 1, shares[2]);
            self.add(sum, i0 + 1, j0 + 1, shares[3]);
        }
    }

    /// The glare of `dot` along whole-pixel rays `whole_rays`, weights `fall` per step:
    /// offsets from the glint's own pixel, clipped to the band and the image once per ray.
    #[inline]
    fn add_axis_rays(&self, sum: &mut [f32], dot: &Dot, whole_rays: &[(i64, i64)], fall: &[f32]) {
        let (wu, row0, rows) = (self.width, self.row0, self.rows);
        let (xi, yi) = (floor_i64(dot.x), floor_i64(dot.y));
        for &(dx, dy) in whole_rays {
            let (mut lo, mut hi) = (1i64, fall.len() as i64);
            for (p, d, limit_lo, limit_hi) in [(xi, dx, 0, wu as i64 - 1), (yi, dy, row0, row0 + rows - 1)] {
                // limit_lo ≤ p + d·step ≤ limit_hi
                match d {
                    0 if p < limit_lo || p > limit_hi => hi = 0,
                    1 => (lo, hi) = (lo.max(limit_lo - p), hi.min(limit_hi - p)),
                    -1 => (lo, hi) = (lo.max(p - limit_hi), hi.min(p - limit_lo)),
                    _ => {}
                }
            }
            for step in lo..=hi {
                let at = (yi + dy * step - row0) as usize * wu + (xi + dx * step) as usize;
                sum[at] += fall[step as usize - 1];
            }
        }
    }

    /// The glare of `dot` along rays in any direction `rays`, weights `fall` per step:
    /// each ray pixel at its position along the ray, dropped outside the band.
    #[inline]
    fn add_rays(&self, sum: &mut [f32], dot: &Dot, rays: &[(f32, f32)], fall: &[f32]) {
        for &(dx, dy) in rays {
            for (step, f) in fall.iter().enumerate() {
                let step = (step + 1) as f32;
                let (qx, qy) = (dot.x + dx * step, dot.y + dy * step);
                if qx >= 0.0 && qy >= 0.0 {
                    self.add(sum, qx as i64, qy as i64, *f);
                }
            }
        }
    }
}

/// The bilinear shares of up to [`LANES`] dots among the four pixels around each (as
/// `Plane::deposit_bilinear`: pixel centres at +0.5), worked out in lanes with the
/// scalar operations in the scalar order.
struct Bilinear {
    /// Bit k: dot k has a pixel at or right of / below column and row -1.
    inside: u32,
    /// Column and row of the top-left pixel of the four.
    i0: [i32; LANES],
    j0: [i32; LANES],
    /// Shares of the top-left, top-right, bottom-left and bottom-right pixels.
    share: [[f32; LANES]; 4],
}

impl Bilinear {
    #[inline]
    fn of(dots: &[Dot]) -> Self {
        let lanes = |f: fn(&Dot) -> f32| {
            let mut a = [f(&dots[0]); LANES];
            for (v, d) in a.iter_mut().zip(dots) {
                *v = f(d);
            }
            f32x8::from(a)
        };
        let (x, y, v) = (lanes(|d| d.x), lanes(|d| d.y), lanes(|d| d.core));
        let (half, one) = (f32x8::splat(0.5), f32x8::ONE);
        let (fx, fy) = (x - half, y - half);
        let inside = (fx.simd_ge(-one) & fy.simd_ge(-one)).to_bitmask() & ((1u32 << dots.len()) - 1);
        // floor without a libm call: truncation of values at or above 0 (dots lie within
        // the image and its glare margin, far below 2³¹). Other lanes are not used: a
        // non-finite value gives i32::MIN, wrapped by the - 1, and fails the bounds
        // checks of the caller too.
        let (i0, j0) = ((fx + one).fast_trunc_int() - i32x8::ONE, (fy + one).fast_trunc_int() - i32x8::ONE);
        let (tx, ty) = (fx - i0.round_float(), fy - j0.round_float());
        let (sx, sy) = (one - tx, one - ty);
        Self {
            inside,
            i0: i0.to_array(),
            j0: j0.to_array(),
            share: [v * (sx * sy), v * (tx * sy), v * (sx * ty), v * (tx * ty)].map(|s| s.to_array()),
        }
    }
}

/// ⌊x⌋ for |x| < 2⁶³ without a libm call (baseline x86-64 has no rounding instruction).
#[inline]
fn floor_i64(x: f32) -> i64 {
    let t = x as i64;
    t - i64::from((t as f32) > x)
}

/// A glint on screen: position (px), brightness, the part of it drawn at its point,
/// its footprint's reach for the rays or the lens (px, 0 for none); with a lens, its
/// defocus radius and glare length (px) and the sum of its spread's weights.
#[derive(Clone, Copy, Debug, Default)]
struct Dot {
    x: f32,
    y: f32,
    value: f32,
    core: f32,
    len: f32,
    blur: f32,
    bloom: f32,
    norm: f32,
}

/// What places glints on screen: the view, the brightness rules and the image's bands.
struct Screen<'w> {
    /// The view as numbers, when it is perspective or orthographic (projected in lanes).
    pinhole: Option<Pinhole>,
    eye: Vec3,
    /// Square of `falloff_from_m` (0: no falloff).
    falloff2: f32,
    /// k_s I_l.
    peak: f32,
    /// Glare length of the brightest glint, px (0: no glare).
    glare_length: f32,
    glare_threshold: f32,
    /// The lens's defocus, with `glare = "lens"` and a perspective view.
    lens: Option<Lens>,
    /// Image width and height, px.
    size: (f32, f32),
    last_band: u32,
    /// The depths a glint is drawn at (all when `None`).
    window: Option<DepthWindow<'w>>,
}

/// Which glints to draw, by depth, when glints are composed with other phenomena: a
/// glint at distance d along the view direction is drawn when `near_m ≤ d` and, where
/// `far_m` is given (per pixel, row-major, the frame's size: the nearest opaque
/// surface), d < the value at its pixel (the nearest pixel for a glint just off the
/// image). A drawn glint's glare is drawn whole.
#[derive(Clone, Copy, Debug, Default)]
pub struct DepthWindow<'a> {
    /// Nearest depth drawn, metres.
    pub near_m: f32,
    /// Per pixel, the depth from which glints are hidden, metres.
    pub far_m: Option<&'a [f32]>,
}

impl DepthWindow<'_> {
    fn keeps(&self, x_px: f32, y_px: f32, depth: f32, width: usize) -> bool {
        if depth.is_nan() || depth < self.near_m {
            return false;
        }
        match self.far_m {
            None => true,
            Some(far) => {
                // A glint just off the image (whose glare reaches in) is judged by the
                // nearest pixel on the image.
                let height = far.len() / width.max(1);
                if width == 0 || height == 0 {
                    return true;
                }
                let x = (x_px.max(0.0) as usize).min(width - 1);
                let y = (y_px.max(0.0) as usize).min(height - 1);
                depth < far[y * width + x]
            }
        }
    }
}

impl Screen<'_> {
    /// Project up to [`LANES`] glints (positions `xc`, brightness `ic`) and hand each one
    /// whose footprint (its pixel and glare) touches the image to `keep`, with the first
    /// and last band it touches, in glint order. Eight at a time in lanes: a glint's
    /// place and brightness take the scalar operations in the scalar order
    /// ([`CameraView::project`] and the rules of [`RenderSettings`]), so lanes give the
    /// same bits.
    #[inline]
    fn place(&self, view: &CameraView, xc: &[Vec3], ic: &[f32], mut keep: impl FnMut(Dot, u32, u32)) {
        let x = V8::load(xc);
        let mut value = [ic[0]; LANES];
        value[..ic.len()].copy_from_slice(ic);
        let mut value = f32x8::from(value);
        let (px, py, ok, depth) = match &self.pinhole {
            Some(ph) => {
                let d = x.sub(V8::splat(ph.eye));
                let depth = d.dot(V8::splat(ph.forward));
                let scale = f32x8::splat(ph.scale);
                let (s, ok) = if ph.perspective {
                    (scale / depth, depth.simd_gt(f32x8::splat(NEAR_M)).to_bitmask())
                } else {
                    (scale, u32::MAX)
                };
                let px = f32x8::splat(ph.centre_px.0) + d.dot(V8::splat(ph.right)) * s;
                let py = f32x8::splat(ph.centre_px.1) - d.dot(V8::splat(ph.up)) * s;
                (px, py, ok, depth.to_array())
            }
            None => {
                // Fisheye and equirectangular views: one glint at a time.
                let (mut px, mut py, mut ok, mut depth) = ([0.0; LANES], [0.0; LANES], 0u32, [0.0; LANES]);
                for (i, p) in xc.iter().enumerate() {
                    if let Some(q) = view.project(*p) {
                        (px[i], py[i], depth[i]) = (q.x_px, q.y_px, q.depth);
                        ok |= 1 << i;
                    }
                }
                (f32x8::from(px), f32x8::from(py), ok, depth)
            }
        };
        if self.falloff2 > 0.0 {
            let d = x.sub(V8::splat(self.eye));
            value *= (f32x8::splat(self.falloff2) / d.dot(d)).min(f32x8::ONE);
        }
        let one = f32x8::ONE;
        let len = if self.glare_length > 0.0 {
            let rel = value / f32x8::splat(self.peak);
            let long = (f32x8::splat(self.glare_length) * rel.sqrt()).max(one);
            rel.simd_ge(f32x8::splat(self.glare_threshold)).select(long, f32x8::ZERO)
        } else {
            f32x8::ZERO
        };
        // With a lens: the defocus disc's radius, px, and the glare (bloom) length capped
        // as the rays are; the footprint reaches the larger.
        let (bloom, blur) = match self.lens {
            Some(lens) => (len.min(f32x8::splat(MAX_RAY_PX as f32)), lens.radius_px(f32x8::from(depth))),
            None => (f32x8::ZERO, f32x8::ZERO),
        };
        let len = if self.lens.is_some() { bloom.max(blur) } else { len };
        let m = len + one;
        let (w, h) = (f32x8::splat(self.size.0), f32x8::splat(self.size.1));
        let inside = px.simd_gt(-m) & py.simd_gt(-m) & px.simd_lt(w + m) & py.simd_lt(h + m);
        // Bands of rows its footprint touches (through u32 lanes: the values are
        // non-negative and below 2³¹ for every glint kept).
        let band = |v: f32x8| {
            let rows: u32x8 = wide::bytemuck::cast(v.fast_trunc_int());
            (rows >> BAND_ROWS.trailing_zeros()).min(u32x8::splat(self.last_band)).to_array()
        };
        let lo = band((py - len - one).max(f32x8::ZERO));
        let hi = band((py + len + one).max(f32x8::ZERO).min(h - one));
        let mut kept = ok & inside.to_bitmask() & ((1u32 << xc.len()) - 1);
        let (px, py, value, len) = (px.to_array(), py.to_array(), value.to_array(), len.to_array());
        let (blur, bloom) = (blur.to_array(), bloom.to_array());
        while kept != 0 {
            let i = kept.trailing_zeros() as usize;
            kept &= kept - 1;
            if let Some(window) = &self.window
                && !window.keeps(px[i], py[i], depth[i], self.size.0 as usize)
            {
                continue;
            }
            let dot =
                Dot { x: px[i], y: py[i], value: value[i], core: value[i], len: len[i], ..Dot::default() };
            keep(self.with_lens(dot, blur[i], bloom[i]), lo[i], hi[i]);
        }
    }

    /// `dot` with the lens's defocus radius `blur` and bloom length `bloom` (px): a
    /// defocused glint's light is all in its disc, a sharp one's in its pixel; and the sum
    /// of its spread's weights. Unchanged without a lens.
    fn with_lens(&self, mut dot: Dot, blur: f32, bloom: f32) -> Dot {
        if self.lens.is_none() {
            return dot;
        }
        (dot.blur, dot.bloom) = (blur, bloom);
        if blur >= 1.0 {
            dot.core = 0.0;
        }
        dot.norm = LensSpread::of(&dot, 1.0).map_or(0.0, |spread| spread.norm(&dot));
        dot
    }
}

/// A thin lens's defocus: a point at depth d, with the plane at `focus` m in focus,
/// spreads over a disc of radius k |d − focus| / d px.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Lens {
    k: f32,
    focus: f32,
}

impl Lens {
    /// The lens of `s` on a 35 mm full-frame camera (sensor 24 mm high) with the view's
    /// field of view: focal length f = 0.024 m · f_px / height_px, aperture A = f / N,
    /// and the circle of confusion's diameter C = A f_px |d − s| / (d (s − f)) px (the
    /// thin-lens formula, in pixels through f_px / f). `None` for a pinhole (N = 0), a
    /// view other than perspective, or a focus nearer than the focal length.
    fn of(s: &RenderSettings, view: &CameraView, height_px: usize) -> Option<Self> {
        let ph = view.pinhole().filter(|p| p.perspective)?;
        if !(s.aperture_f_number > 0.0) {
            return None;
        }
        let f_m = 0.024 * ph.scale / height_px as f32;
        let aperture = f_m / s.aperture_f_number;
        (s.focus_m > f_m).then(|| Self { k: 0.5 * aperture * ph.scale / (s.focus_m - f_m), focus: s.focus_m })
    }

    /// The defocus radius at `depth` m, px (at most [`MAX_RAY_PX`]).
    #[inline]
    fn radius_px(&self, depth: f32x8) -> f32x8 {
        let r =
            f32x8::splat(self.k) * (depth - f32x8::splat(self.focus)).abs() / depth.max(f32x8::splat(NEAR_M));
        r.min(f32x8::splat(MAX_RAY_PX as f32))
    }
}

/// Schlick's Fresnel reflectance of a facet of index `ior` and normal `n` at `x` lit
/// from `light`, over its value at normal incidence: 1 + (1/F0 − 1)(1 − |N·L|)⁵.
fn fresnel_gain(ior: f32, light: LightAt, x: Vec3, n: Vec3) -> f32 {
    let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
    let l = match light {
        LightAt::Direction(d) => d,
        LightAt::Position(p) => (p - x).normalize_or_zero(),
    };
    let c = (1.0 - n.dot(l).abs()).clamp(0.0, 1.0);
    1.0 + (1.0 / f0 - 1.0) * c.powi(5)
}

/// How a lens spreads one glint: a defocused glint (defocus radius ≥ 1 px) as a uniform
/// disc of that radius holding all its light, each pixel weighted by how much of it the
/// disc covers (its centre within the radius ± half a pixel); a sharp glint bright
/// enough for glare as a bloom of radius max(glare length, 1) px adding `strength` times
/// its light, falling off as (1 − r / radius)²; a sharp dim glint not at all.
struct LensSpread {
    radius: f32,
    total: f32,
    disc: bool,
}

impl LensSpread {
    fn of(dot: &Dot, strength: f32) -> Option<Self> {
        if dot.blur >= 1.0 {
            Some(Self { radius: dot.blur, total: dot.value, disc: true })
        } else if dot.bloom > 0.0 {
            Some(Self { radius: dot.bloom.max(1.0), total: strength * dot.value, disc: false })
        } else {
            None
        }
    }

    /// The pixel of the glint and how far the footprint reaches from it, px.
    fn window(&self, dot: &Dot) -> (i64, i64, i64) {
        (floor_i64(dot.x), floor_i64(dot.y), self.radius.ceil() as i64 + 1)
    }

    /// The weight of pixel (i, j), one at a time: the definition [`LensSpread::weight8`]
    /// follows.
    #[cfg(test)]
    fn weight(&self, dot: &Dot, i: i64, j: i64) -> f32 {
        let (dx, dy) = (i as f32 + 0.5 - dot.x, j as f32 + 0.5 - dot.y);
        let r = (dx * dx + dy * dy).sqrt();
        if self.disc {
            (self.radius + 0.5 - r).clamp(0.0, 1.0)
        } else {
            let t = 1.0 - r / self.radius;
            if r > 0.0 && t > 0.0 { t * t } else { 0.0 }
        }
    }

    /// The columns of row `j` of the window ([`LensSpread::window`]) that may have a
    /// weight above 0, a pixel wider each side than the circle where the weight ends
    /// (r < radius + ½ for a disc, r < radius for a bloom): every column left out has
    /// weight 0 exactly, so sums over the span are the sums over the window. `None`
    /// for a row wholly outside.
    fn span(&self, dot: &Dot, j: i64, (xi, reach): (i64, i64)) -> Option<(i64, i64)> {
        let end = if self.disc { self.radius + 0.5 } else { self.radius };
        let dy = j as f32 + 0.5 - dot.y;
        let across = end * end - dy * dy;
        if dy.abs() > end + 1.0 || !(across > -1.0) {
            return None;
        }
        let half = across.max(0.0).sqrt();
        let lo = floor_i64(dot.x - 0.5 - half) - 1;
        let hi = floor_i64(dot.x - 0.5 + half) + 2;
        Some((lo.max(xi - reach), hi.min(xi + reach)))
    }

    /// The sum of the weights over the whole footprint.
    fn norm(&self, dot: &Dot) -> f32 {
        let (xi, yi, reach) = self.window(dot);
        let mut norm = 0.0;
        for j in yi - reach..=yi + reach {
            let Some((i0, i1)) = self.span(dot, j, (xi, reach)) else { continue };
            // Eight weights at a time, added one by one in order.
            for i in (i0..=i1).step_by(LANES) {
                let w = self.weight8(dot, i, j).to_array();
                w[..(i1 - i + 1).min(LANES as i64) as usize].iter().for_each(|w| norm += w);
            }
        }
        norm
    }

    /// The weights of columns `i..i + 8` of row `j`: lane by lane the IEEE operations of
    /// [`LensSpread::weight`] in its order (test `lanes_weigh_as_the_scalar_spread`).
    /// Column numbers below 2²³ are exact in f32, so i + k is formed exactly in lanes.
    #[inline(always)]
    fn weight8(&self, dot: &Dot, i: i64, j: i64) -> f32x8 {
        let columns = f32x8::splat(i as f32) + f32x8::from([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let dx = columns + f32x8::splat(0.5) - f32x8::splat(dot.x);
        let dy = f32x8::splat(j as f32 + 0.5 - dot.y);
        let r = (dx * dx + dy * dy).sqrt();
        if self.disc {
            (f32x8::splat(self.radius + 0.5) - r).max(f32x8::ZERO).min(f32x8::ONE)
        } else {
            let t = f32x8::ONE - r / f32x8::splat(self.radius);
            (r.simd_gt(f32x8::ZERO) & t.simd_gt(f32x8::ZERO)).select(t * t, f32x8::ZERO)
        }
    }
}

/// Glints per parallel projection chunk (fixed: the frame does not depend on threads).
const PROJECT_CHUNK: usize = 8192;

/// The sky, sun disc, ground and (leaf glitter) the Lambert-shaded crown, per pixel.
fn sky(s: &RenderSettings, view: &CameraView, light: LightAt, population: &Population) -> Frame {
    let (w, h) = view.size();
    let zenith = Vec3::from(s.sky_zenith_rgb);
    let horizon = Vec3::from(s.sky_horizon_rgb);
    let ground = Vec3::from(s.ground_rgb);
    let crown = Vec3::from(s.crown_rgb);
    let sun = match light {
        LightAt::Direction(d) => Some(d),
        LightAt::Position(_) => None,
    };
    let dome = match population {
        Population::LeafGlitter(l) => Some((l.centre_m, l.radius_m, l.spread_deg.to_radians().tan())),
        Population::DiamondDust(_) => None,
    };
    // The sun's disc (0.27° radius) and a soft aureole.
    let cos_disc = 0.27f32.to_radians().cos();
    let rows: Vec<Vec<Vec3>> = (0..h)
        .into_par_iter()
        .map(|j| {
            (0..w)
                .map(|i| {
                    let (o, d) = view.ray(i as f32 + 0.5, j as f32 + 0.5);
                    let lit = |n: Vec3| match light {
                        LightAt::Direction(l) => 0.15 + 0.85 * n.dot(l).max(0.0),
                        LightAt::Position(p) => 0.15 + 0.85 * n.dot((p - o).normalize_or_zero()).max(0.0),
                    };
                    if let Some((c, r, tilt)) = dome {
                        let oc = o - c;
                        let b = oc.dot(d);
                        let disc = b * b - (oc.length_squared() - r * r);
                        if disc >= 0.0 {
                            let t = -b - disc.sqrt();
                            let p = o + d * t;
                            if t > 0.0 && p.y >= c.y {
                                return crown * crown_light(p, (p - c) / r, tilt, light, zenith);
                            }
                        }
                        if d.y < 0.0 {
                            return ground * lit(Vec3::Y);
                        }
                    } else if d.y < 0.0 {
                        return ground * (0.6 + 0.4 * (-d.y).min(1.0));
                    }
                    let e = d.y.clamp(0.0, 1.0);
                    let mut c = horizon + (zenith - horizon) * e.sqrt();
                    if let Some(l) = sun {
                        let cs = d.dot(l);
                        if cs >= cos_disc {
                            c += Vec3::splat(200.0);
                        } else if cs > 0.0 {
                            c += Vec3::new(1.0, 0.9, 0.7) * 0.25 * cs.powf(64.0);
                        }
                    }
                    c
                })
                .collect()
        })
        .collect();
    let mut f = Frame::new(w, h);
    for (j, row) in rows.iter().enumerate() {
        for (i, c) in row.iter().enumerate() {
            f.set_pixel(i, j, *c);
        }
    }
    f
}

/// Size of a clump of leaves that turns one way, m (with sprays a third of it inside).
const CLUMP_M: f32 = 0.3;

/// The light on the crown at `p` (outward normal `n0`): leaves in clumps, each clump's
/// normal tilted from the crown's by a smooth random field times `tilt` (tan of the
/// leaves' spread; the field's sideways part is mostly under 1, at most about 2.1, so
/// clumps tilt mostly within the spread and at most about 44° for 25°), lit by the sun (Lambert), by the sky (the half of it a normal
/// sees, in the sky's zenith colour, darker in a clump's hollows) and, from behind, by
/// the sun through the leaves (translucency). An extension: §3.2 draws only the glints.
fn crown_light(p: Vec3, n0: Vec3, tilt: f32, light: LightAt, zenith: Vec3) -> Vec3 {
    // Clumps, and smaller sprays of leaves within them.
    let field = clump_field(p / CLUMP_M) + 0.5 * clump_field(p * (3.0 / CLUMP_M));
    let side = field - n0 * field.dot(n0);
    let n = (n0 + side * tilt).normalize_or(n0);
    let l = match light {
        LightAt::Direction(l) => l,
        LightAt::Position(q) => (q - p).normalize_or_zero(),
    };
    // The field's length (0 to 1.5√3) is how open the clump is: hollows see less sky.
    let open = (0.55 + 0.3 * field.length()).min(1.0);
    let sun = 0.85 * n.dot(l).max(0.0);
    let through = 0.25 * (-n0.dot(l)).max(0.0);
    let sky = (zenith / zenith.max_element().max(1e-6)) * 0.3 * (0.5 + 0.5 * n.y) * open;
    Vec3::splat(sun + through) + sky
}

/// A smooth random vector field (each component in [-1, 1]): random vectors at the
/// integer lattice, blended with smoothstep weights. Deterministic in `q` alone.
fn clump_field(q: Vec3) -> Vec3 {
    let base = q.floor();
    let f = q - base;
    let w = f * f * (Vec3::splat(3.0) - 2.0 * f);
    let mut sum = Vec3::ZERO;
    for corner in 0..8u32 {
        let o = Vec3::new((corner & 1) as f32, ((corner >> 1) & 1) as f32, ((corner >> 2) & 1) as f32);
        let k = base + o;
        let weight = (if o.x > 0.0 { w.x } else { 1.0 - w.x })
            * (if o.y > 0.0 { w.y } else { 1.0 - w.y })
            * (if o.z > 0.0 { w.z } else { 1.0 - w.z });
        let mut h = (k.x as i32 as u32 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (k.y as i32 as u32 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ (k.z as i32 as u32 as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
        let mut next = || {
            h ^= h >> 33;
            h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
            h ^= h >> 33;
            (h >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        sum += Vec3::new(next(), next(), next()) * weight;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SparkleConfig;

    /// Sparse diamond dust with wide lobes (n = 100): a few hundred glints in view.
    fn sparse_dust() -> SparkleSim {
        let mut c = SparkleConfig::default();
        c.phong.exponent_n = 100.0;
        if let Population::DiamondDust(d) = &mut c.population {
            d.density_per_m3 = 1.0;
        }
        SparkleSim::new(c, 3).unwrap()
    }

    /// Depth windows split the glints without loss or overlap: the glints nearer than
    /// a depth and those from it on sum to all of them over black (to f32 rounding of
    /// the per-pixel sums, 1e-5 relative), an opaque surface at zero depth hides them
    /// all, and the full window draws exactly what the black background does.
    #[test]
    fn depth_windows_split_the_glints_and_surfaces_hide_them() {
        let sim = sparse_dust();
        let plain = RenderSettings { background: Background::Black, ..Default::default() };
        let mut r = SparkleRenderer::new(plain, 160, 90, None).unwrap();
        let all = r.render(&sim).clone();
        let everything = r.render_glints(&sim, DepthWindow::default()).clone();
        assert_eq!(everything, all, "the full window is the glints over black");
        // Split at the median depth, so both sides hold glints.
        let view = sim.config().camera.view(160, 90).unwrap();
        let mut depths: Vec<f32> =
            sim.glints().position_m.iter().filter_map(|x| view.project(*x)).map(|p| p.depth).collect();
        depths.sort_by(f32::total_cmp);
        let split = depths[depths.len() / 2];
        let far = r.render_glints(&sim, DepthWindow { near_m: split, far_m: None }).clone();
        let wall = vec![split; 160 * 90];
        let near = r.render_glints(&sim, DepthWindow { near_m: 0.0, far_m: Some(&wall) }).clone();
        let (a, b, n) = (all.c1.sum(), far.c1.sum(), near.c1.sum());
        assert!(b > 0.0 && n > 0.0, "both sides hold light: {b} {n}");
        assert!((b + n - a).abs() <= 1e-5 * a, "{b} + {n} vs {a}");
        let hidden = vec![0.0; 160 * 90];
        let none = r.render_glints(&sim, DepthWindow { near_m: 0.0, far_m: Some(&hidden) });
        assert_eq!(none.c1.sum(), 0.0, "a surface at the eye hides every glint");
    }

    #[test]
    fn glints_add_light_over_the_background() {
        let sim = sparse_dust();
        assert!(sim.glints().len() > 100);
        let mut r = SparkleRenderer::new(RenderSettings::default(), 160, 90, None).unwrap();
        let with = r.render(&sim).clone();
        let mut none = SparkleRenderer::new(
            RenderSettings { glint_gain: 0.0, glare: GlareShape::None, ..RenderSettings::default() },
            160,
            90,
            None,
        )
        .unwrap();
        let without = none.render(&sim).clone();
        let sum = |f: &Frame| f.c1.sum();
        assert!(sum(&with) > sum(&without) + 1e-3, "{} vs {}", sum(&with), sum(&without));
        assert!(RenderSettings { glint_gain: -1.0, ..Default::default() }.validate().is_err());
        // The glints' light is all there: with no glare and a black background the frame
        // sums to between Σ gain × intensity over glints whose whole bilinear footprint is
        // on screen and the same over glints that touch the screen at all.
        let plain = RenderSettings {
            background: Background::Black,
            glare: GlareShape::None,
            glint_gain: 1.0,
            light_rgb: [1.0; 3],
            falloff_from_m: 0.0, // the paper's brightness: each glint's intensity as is
            ..Default::default()
        };
        let view = sim.config().camera.view(160, 90).unwrap();
        let sum_within = |m: f32| -> f64 {
            sim.glints()
                .position_m
                .iter()
                .zip(&sim.glints().intensity)
                .filter_map(|(x, &i)| view.project(*x).map(|p| (p, i)))
                .filter(|(p, _)| p.x_px >= m && p.y_px >= m && p.x_px <= 160.0 - m && p.y_px <= 90.0 - m)
                .map(|(_, i)| f64::from(i))
                .sum()
        };
        let (full, touching) = (sum_within(0.5), sum_within(-0.5));
        let mut r = SparkleRenderer::new(plain, 160, 90, None).unwrap();
        let total = r.render(&sim).c1.sum();
        // 1e-4 relative: f32 sums of ~10³ terms.
        assert!(
            full > 1.0 && total >= full * (1.0 - 1e-4) && total <= touching * (1.0 + 1e-4),
            "{full} {total} {touching}"
        );
    }

    #[test]
    fn bands_add_glints_and_glare_as_a_plain_loop_over_the_image_does() {
        // Reference: every glint added straight into the whole image (no bands, no
        // filing, f64 sums). Band edges, clipping at the image border and ray weights
        // must all agree; the difference is f32 rounding only (1e-5 of the brightest
        // pixel: sums of at most a few hundred terms).
        let mut c = SparkleConfig::default();
        c.phong.exponent_n = 100.0;
        if let Population::DiamondDust(d) = &mut c.population {
            d.density_per_m3 = 1.0;
        }
        let sim = SparkleSim::new(c, 4).unwrap();
        let peak = c.phong.specular_k_s * c.phong.light_intensity;
        for glare in [GlareShape::Cross, GlareShape::Star] {
            let s = RenderSettings {
                background: Background::Black,
                glare,
                glare_threshold: 0.3,
                glare_length_px: 20.0,
                glare_strength: 0.5,
                glint_gain: 1.0,
                light_rgb: [1.0; 3],
                falloff_from_m: 0.0, // the plain loop below has no falloff
                ..Default::default()
            };
            let (w, h) = (200usize, 120usize);
            let view = sim.config().camera.view(w, h).unwrap();
            let mut want = vec![0.0f64; w * h];
            let mut add = |i: i64, j: i64, v: f32| {
                if i >= 0 && j >= 0 && (i as usize) < w && (j as usize) < h {
                    want[j as usize * w + i as usize] += f64::from(v);
                }
            };
            let rays = glare.rays();
            let mut glared = 0;
            for (x, &v) in sim.glints().position_m.iter().zip(&sim.glints().intensity) {
                let Some(p) = view.project(*x) else { continue };
                let (fx, fy) = (p.x_px - 0.5, p.y_px - 0.5);
                let (i0, j0) = (fx.floor(), fy.floor());
                let (tx, ty) = (fx - i0, fy - j0);
                let (i0, j0) = (i0 as i64, j0 as i64);
                add(i0, j0, v * (1.0 - tx) * (1.0 - ty));
                add(i0 + 1, j0, v * tx * (1.0 - ty));
                add(i0, j0 + 1, v * (1.0 - tx) * ty);
                add(i0 + 1, j0 + 1, v * tx * ty);
                let rel = v / peak;
                if rel < s.glare_threshold {
                    continue;
                }
                glared += 1;
                let len = (s.glare_length_px * rel.sqrt()).max(1.0);
                for &(dx, dy) in rays {
                    for k in 1..=len.ceil() as i64 {
                        let t = k as f32 / len;
                        if t > 1.0 {
                            break;
                        }
                        let f = v * (1.0 - t) * (1.0 - t) * s.glare_strength / len;
                        let (qx, qy) = if glare == GlareShape::Cross {
                            (p.x_px.floor() as i64 + dx as i64 * k, p.y_px.floor() as i64 + dy as i64 * k)
                        } else {
                            let (qx, qy) = (p.x_px + dx * k as f32, p.y_px + dy * k as f32);
                            if qx < 0.0 || qy < 0.0 {
                                continue;
                            }
                            (qx as i64, qy as i64)
                        };
                        add(qx, qy, f);
                    }
                }
            }
            assert!(glared > 50, "{glared}");
            let got = SparkleRenderer::new(s, w, h, None).unwrap().render(&sim).c1.clone();
            let top = want.iter().fold(0.0f64, |a, &b| a.max(b));
            let worst =
                got.data().iter().zip(&want).map(|(&g, &r)| (f64::from(g) - r).abs()).fold(0.0, f64::max);
            assert!(top > 0.0 && worst <= 1e-5 * top, "{glare:?}: {worst} of {top}");
        }
    }

    /// 1003 glints (position, brightness) in front of, beside and behind the default
    /// camera.
    fn glints_around_the_camera() -> Vec<(Vec3, f32)> {
        let mut rng =
            phenomena_core::rng::Stream::new(1, phenomena_core::rng::Purpose::named("test.place"), 0);
        (0..1003)
            .map(|_| {
                let x =
                    Vec3::new(rng.uniform(-30.0, 30.0), rng.uniform(-5.0, 25.0), rng.uniform(-60.0, 20.0));
                (x, rng.uniform(0.0, 1.0))
            })
            .collect()
    }

    /// A placed dot: x, y, brightness, glare length, first and last band.
    type Placed = (f32, f32, f32, f32, u32, u32);

    /// The dots `screen` (falloff2 64, peak 1, glare 9 px from 0.4) should place, by the
    /// scalar rules: `CameraView::project`, falloff, glare length and bands.
    fn placed_one_at_a_time(glints: &[(Vec3, f32)], view: &CameraView, screen: &Screen) -> Vec<Placed> {
        let (w, h) = screen.size;
        let mut want = Vec::new();
        for &(x, v) in glints {
            let Some(p) = view.project(x) else { continue };
            let v = v * (64.0 / (x - screen.eye).length_squared()).min(1.0);
            let len = if v >= 0.4 { (9.0 * v.sqrt()).max(1.0) } else { 0.0 };
            let m = len + 1.0;
            if p.x_px > -m && p.y_px > -m && p.x_px < w + m && p.y_px < h + m {
                let band = |y: f32| (y as u32 / BAND_ROWS as u32).min(screen.last_band);
                let (lo, hi) =
                    (band((p.y_px - len - 1.0).max(0.0)), band((p.y_px + len + 1.0).clamp(0.0, h - 1.0)));
                want.push((p.x_px, p.y_px, v, len, lo, hi));
            }
        }
        want
    }

    /// The bilinear shares of `dots` in lanes ([`Bilinear::of`]) equal the scalar ones, bit
    /// for bit.
    fn assert_bilinear_is_scalar(dots: &[Dot]) {
        for group in dots.chunks(LANES) {
            let four = Bilinear::of(group);
            for (k, d) in group.iter().enumerate() {
                let (fx, fy) = (d.x - 0.5, d.y - 0.5);
                assert_eq!(four.inside & (1 << k) != 0, fx >= -1.0 && fy >= -1.0);
                if fx < -1.0 || fy < -1.0 {
                    continue;
                }
                let (i0, j0) = ((fx + 1.0) as i64 - 1, (fy + 1.0) as i64 - 1);
                let (tx, ty) = (fx - i0 as f32, fy - j0 as f32);
                let v = d.core;
                let shares = [
                    v * ((1.0 - tx) * (1.0 - ty)),
                    v * (tx * (1.0 - ty)),
                    v * ((1.0 - tx) * ty),
                    v * (tx * ty),
                ];
                assert_eq!((i64::from(four.i0[k]), i64::from(four.j0[k])), (i0, j0));
                for (c, share) in shares.iter().enumerate() {
                    assert_eq!(four.share[c][k].to_bits(), share.to_bits());
                }
            }
        }
    }

    #[test]
    fn glints_are_placed_in_lanes_as_one_at_a_time() {
        // `Screen::place` against the scalar rules (`CameraView::project`, falloff,
        // glare length, bands) for glints in front of, beside and behind the camera,
        // through a pinhole (lanes) and a fisheye (scalar projection): same bits.
        let glints = glints_around_the_camera();
        let (w, h) = (320usize, 180usize);
        for projection in [
            phenomena_core::camera::Projection::Perspective { fov_y_deg: 60.0 },
            phenomena_core::camera::Projection::Orthographic { height_m: 40.0 },
            phenomena_core::camera::Projection::Fisheye { fov_deg: 180.0 },
        ] {
            let camera = phenomena_core::camera::Camera { projection, ..SparkleConfig::default().camera };
            let view = camera.view(w, h).unwrap();
            let screen = Screen {
                pinhole: view.pinhole(),
                eye: camera.position,
                falloff2: 64.0,
                peak: 1.0,
                glare_length: 9.0,
                glare_threshold: 0.4,
                lens: None,
                size: (w as f32, h as f32),
                last_band: (h.div_ceil(BAND_ROWS) - 1) as u32,
                window: None,
            };
            let mut got = Vec::new();
            for group in glints.chunks(LANES) {
                let (xs, is): (Vec<Vec3>, Vec<f32>) = group.iter().copied().unzip();
                screen.place(&view, &xs, &is, |d, lo, hi| got.push((d.x, d.y, d.value, d.len, lo, hi)));
            }
            let want = placed_one_at_a_time(&glints, &view, &screen);
            assert!(want.len() > 100 && want.len() < glints.len(), "{}", want.len());
            assert!(want.iter().any(|d| d.3 > 0.0) && want.iter().any(|d| d.4 != d.5));
            let bits = |v: &[Placed]| -> Vec<_> {
                v.iter()
                    .map(|d| (d.0.to_bits(), d.1.to_bits(), d.2.to_bits(), d.3.to_bits(), d.4, d.5))
                    .collect()
            };
            assert_eq!(bits(&got), bits(&want), "{projection:?}");
            // The bilinear shares of the placed dots, in lanes and one at a time.
            let dots: Vec<Dot> = got
                .iter()
                .map(|d| Dot { x: d.0, y: d.1, value: d.2, core: d.2, len: d.3, ..Dot::default() })
                .collect();
            assert_bilinear_is_scalar(&dots);
        }
    }

    #[test]
    fn the_crown_is_lit_by_the_sun_and_mottled_by_its_leaves() {
        // Points 2 cm apart along a 4 m crown's meridians, under a sun from +x at 30°.
        let sun = LightAt::Direction(Vec3::new(30f32.to_radians().cos(), 30f32.to_radians().sin(), 0.0));
        let zenith = Vec3::new(0.35, 0.5, 0.8);
        let tilt = 25f32.to_radians().tan();
        let meridian = |azimuth: f32| -> Vec<Vec3> {
            (0..200)
                .map(|k| {
                    let e = 0.1 + 0.005 * k as f32;
                    Vec3::new(e.cos() * azimuth.cos(), e.sin(), e.cos() * azimuth.sin())
                })
                .collect()
        };
        let light = |n: &[Vec3], tilt: f32| -> Vec<f32> {
            n.iter().map(|&n| crown_light(n * 4.0, n, tilt, sun, zenith).element_sum()).collect()
        };
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        let (towards, away) = (meridian(0.0), meridian(std::f32::consts::PI));
        let (lit, dark) = (mean(&light(&towards, tilt)), mean(&light(&away, tilt)));
        assert!(lit > 2.0 * dark, "the sunward side {lit} is not brighter than the far side {dark}");
        // The leaves' own normals: tilted mostly within the spread (25°) of the crown's, they
        // change a Lambert term of a sun ~40-90° off the normal by ~sin θ · 0.4 rad, tens
        // of per cent from clump to clump; their ratio to the smooth crown's light varies
        // along the meridian by more than 5 %, and changes little over 2 cm (smooth clumps,
        // not per-pixel noise).
        let (leafy, smooth) = (light(&towards, tilt), light(&towards, 0.0));
        let ratio: Vec<f32> = leafy.iter().zip(&smooth).map(|(a, b)| a / b).collect();
        let m = mean(&ratio);
        let spread = (ratio.iter().map(|r| (r - m) * (r - m)).sum::<f32>() / ratio.len() as f32).sqrt() / m;
        let step = ratio.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f32>() / (ratio.len() - 1) as f32 / m;
        assert!(spread > 0.05, "the leaves vary the light by {spread} only");
        assert!(step < 0.25 * spread, "from point to point 2 cm apart the light changes by {step} (noise)");
    }

    #[test]
    fn lanes_weigh_as_the_scalar_spread() {
        // Discs and blooms of every size up to the cap, anywhere on a 16k-pixel image
        // (where f32 rounds coarsest): each lane's weight has the scalar weight's bits.
        let mut h = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            h ^= h << 13;
            h ^= h >> 7;
            h ^= h << 17;
            (h >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut nonzero = 0;
        for k in 0..400 {
            let radius = 1.0 + next() * (MAX_RAY_PX as f32 - 1.0);
            let (x, y) = (next() * 16_384.0 - 8.0, next() * 16_384.0 - 8.0);
            let dot = if k % 2 == 0 {
                Dot { x, y, blur: radius, value: 1.0, ..Dot::default() }
            } else {
                Dot { x, y, bloom: radius, value: 1.0, ..Dot::default() }
            };
            let spread = LensSpread::of(&dot, 1.0).expect("a spread");
            let (xi, yi, reach) = spread.window(&dot);
            for j in (yi - reach..=yi + reach).step_by(3) {
                for i in (xi - reach - 8..=xi + reach).step_by(5) {
                    let lanes = spread.weight8(&dot, i, j).to_array();
                    for (l, w) in lanes.iter().enumerate() {
                        let want = spread.weight(&dot, i + l as i64, j);
                        assert_eq!(w.to_bits(), want.to_bits(), "column {} row {j} of {dot:?}", i + l as i64);
                        nonzero += usize::from(want > 0.0 && want < 1.0);
                    }
                }
            }
        }
        assert!(nonzero > 10_000, "only {nonzero} weights strictly between 0 and 1");
    }

    #[test]
    fn a_lens_spreads_light_by_the_thin_lens_and_keeps_it() {
        // f/2 focused at 10 m, 60° over 720 rows: a point 1 m away. The circle of
        // confusion in millimetres on the 24 mm sensor, f = 12 / tan 30° mm:
        // C = f² / (N (s − f)) · |d − s| / d, then 720 / 24 px per mm.
        let camera = phenomena_core::camera::Camera {
            position: Vec3::ZERO,
            look_at: Vec3::NEG_Z,
            up: Vec3::Y,
            projection: phenomena_core::camera::Projection::Perspective { fov_y_deg: 60.0 },
        };
        let view = camera.view(1280, 720).unwrap();
        let s = RenderSettings {
            glare: GlareShape::Lens,
            aperture_f_number: 2.0,
            focus_m: 10.0,
            ..Default::default()
        };
        let lens = Lens::of(&s, &view, 720).unwrap();
        let f_mm = 12.0 / 30f64.to_radians().tan();
        for d in [0.5f64, 1.0, 4.0, 10.0, 40.0] {
            let c_mm = f_mm * f_mm / (2.0 * (10_000.0 - f_mm)) * (d - 10.0).abs() / d;
            let expected = 0.5 * c_mm * 720.0 / 24.0;
            let got = f64::from(lens.radius_px(f32x8::splat(d as f32)).to_array()[0]);
            assert!(
                (got - expected).abs() <= 1e-4 * expected.max(1.0),
                "{d} m: radius {got} px vs {expected}"
            );
        }
        // A defocused glint keeps all its light in its disc, a sharp one's bloom adds
        // `strength` times its light, wherever the band cuts them.
        for (mut dot, total) in [
            (Dot { x: 30.3, y: 20.7, value: 2.0, len: 5.2, blur: 5.2, ..Dot::default() }, 2.0),
            (
                Dot { x: 30.3, y: 33.9, value: 2.0, core: 2.0, len: 6.0, bloom: 6.0, ..Dot::default() },
                0.35 * 2.0,
            ),
            // Sharp (under a pixel of defocus) and too dim for glare: its pixel only.
            (Dot { x: 30.3, y: 33.9, value: 2.0, core: 2.0, len: 0.6, blur: 0.6, ..Dot::default() }, 0.0),
        ] {
            dot.norm = LensSpread::of(&dot, 1.0).map_or(0.0, |spread| spread.norm(&dot));
            let mut added = 0.0;
            for row0 in (0..64i64).step_by(BAND_ROWS) {
                let band = BandRows { width: 64, row0, rows: BAND_ROWS as i64 };
                let mut sum = vec![0.0f32; 64 * BAND_ROWS];
                band.add_lens(&mut sum, &dot, 0.35);
                added += sum.iter().sum::<f32>();
            }
            assert!((added - total).abs() < 1e-5, "{dot:?}: {added} vs {total}");
        }
    }

    #[test]
    fn fresnel_gain_runs_from_one_at_normal_incidence_to_one_over_f0_at_grazing() {
        // Ice, n = 1.31: F0 = (0.31 / 2.31)² = 0.01801, 1 / F0 = 55.5.
        let f0 = (0.31f32 / 2.31).powi(2);
        let sun = LightAt::Direction(Vec3::Y);
        let at = |n: Vec3| fresnel_gain(1.31, sun, Vec3::ZERO, n);
        assert!((at(Vec3::Y) - 1.0).abs() < 1e-6 && (at(Vec3::NEG_Y) - 1.0).abs() < 1e-6);
        assert!((at(Vec3::X) - 1.0 / f0).abs() < 1e-3 / f0, "{}", at(Vec3::X));
        // 60° incidence: 1 + (1/F0 − 1) / 32 (Schlick's (1 − cos θ)⁵ = 2⁻⁵).
        let n60 = Vec3::new(60f32.to_radians().sin(), 0.5, 0.0);
        assert!((at(n60) - (1.0 + (1.0 / f0 - 1.0) / 32.0)).abs() < 1e-3);
    }

    #[test]
    fn frames_are_identical_for_any_thread_count() {
        let mut c = SparkleConfig::default();
        c.phong.exponent_n = 300.0;
        if let Population::DiamondDust(d) = &mut c.population {
            d.density_per_m3 = 2.0;
        }
        let sim = SparkleSim::new(c, 5).unwrap();
        let settings = RenderSettings { glare: GlareShape::Star, glare_threshold: 0.2, ..Default::default() };
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                SparkleRenderer::new(settings.clone(), 320, 180, None).unwrap().render(&sim).clone()
            })
        };
        assert_eq!(run(1), run(3));
    }
}
