//! Flame rendering per the paper's §5: blackbody colour by temperature (§5.1, Fig 1),
//! times the poly6 radial profile (Fig 2), additively blended with an alpha from density
//! (§5.2); heat shimmer from accumulated kernel-gradient refraction offsets (Figs 3-4)
//! that distort the background near the flame (§5.3).
//!
//! The output is a linear HDR frame in sRGB primaries; tone mapping and encoding happen
//! at the edge (the CLI).
//!
//! Splats are accumulated in horizontal bands of [`BAND_ROWS`] rows processed in parallel;
//! each band adds its particles in index order, so images are bit-identical for any
//! thread count.

use glam::{DVec3, Vec3};
use phenomena_core::bands::Filed;
use phenomena_core::camera::{Camera, CameraView, Projection};
use phenomena_core::color::{Observer, blackbody_srgb_normalized, blackbody_xyz, xyz_to_linear_srgb};
use phenomena_core::image::{Frame, Plane, par_chunks5};
use phenomena_core::lanes::{LANES, add, load};
use phenomena_core::phenomenon::{RenderError, check_size, image_background};
use phenomena_core::validate::{InvalidConfig, Issue, Issues};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wide::f32x8;

use crate::config::FlameConfig;
use crate::sim::{FlameSim, Particles};

/// Rows per parallel band of the splat buffers.
pub const BAND_ROWS: usize = 16;

/// Largest magnitude of the normalised poly6 gradient profile q(1 - q²)², reached at
/// q = 1/√5: (1/√5)(4/5)² = 0.286217... The paper's Fig 3 texture is normalised to it.
const GRADIENT_PROFILE_MAX: f32 = 0.286_216_5;

/// How bright a temperature looks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Brightness {
    /// Colour only, largest sRGB component 1 at every temperature: the paper's Fig 1
    /// texture, where temperature picks the hue.
    Normalized,
    /// Blackbody radiance relative to `reference_temperature_k`: hotter is brighter, and a
    /// cooling particle dims as Planck's law says (an extension).
    #[default]
    Radiometric,
}

/// What to draw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum View {
    /// The flame over its (shimmering) background (Fig 8).
    #[default]
    Flame,
    /// Each particle as a square, redder where denser, over black (Fig 7).
    Density,
}

/// Heat shimmer (§5.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Shimmer {
    /// Whether to distort the background.
    pub enabled: bool,
    /// Largest background displacement from one particle, metres at the particle's depth
    /// (converted to pixels by the camera, so it does not depend on the resolution).
    pub strength_m: f32,
    /// Radius of a particle's refraction footprint relative to its flame splat.
    pub radius_scale: f32,
}

impl Default for Shimmer {
    fn default() -> Self {
        Self { enabled: true, strength_m: 0.002, radius_scale: 1.0 }
    }
}

/// The image behind the flame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Background {
    /// Black: the flame alone, for additive compositing.
    Black,
    /// A checkerboard in image space, the clearest way to see shimmer.
    Checker {
        /// Checker squares per image height.
        #[serde(default = "default_squares")]
        squares_per_height: f32,
        /// Linear RGB of the light squares.
        #[serde(default = "default_light", deserialize_with = "phenomena_core::serde_vec::vec3")]
        light: Vec3,
        /// Linear RGB of the dark squares.
        #[serde(default = "default_dark", deserialize_with = "phenomena_core::serde_vec::vec3")]
        dark: Vec3,
    },
    /// A vertical gradient from `horizon` (bottom) to `zenith` (top), linear RGB.
    Sky {
        /// Colour at the top of the image.
        #[serde(default = "default_zenith", deserialize_with = "phenomena_core::serde_vec::vec3")]
        zenith: Vec3,
        /// Colour at the bottom of the image.
        #[serde(default = "default_horizon", deserialize_with = "phenomena_core::serde_vec::vec3")]
        horizon: Vec3,
    },
    /// A PNG file, stretched to the frame; the path is relative to the scene file. The
    /// caller loads it and passes it to [`FlameRenderer::new`].
    Image {
        /// Path of the PNG.
        path: std::path::PathBuf,
    },
}

fn default_squares() -> f32 {
    12.0
}
fn default_light() -> Vec3 {
    Vec3::splat(0.08)
}
fn default_dark() -> Vec3 {
    Vec3::splat(0.02)
}
fn default_zenith() -> Vec3 {
    Vec3::new(0.004, 0.006, 0.02)
}
fn default_horizon() -> Vec3 {
    Vec3::new(0.07, 0.035, 0.03)
}

impl Default for Background {
    fn default() -> Self {
        Background::Checker {
            squares_per_height: default_squares(),
            light: default_light(),
            dark: default_dark(),
        }
    }
}

/// Render settings of a flame scene (`[flame.render]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSettings {
    /// The camera.
    pub camera: Camera,
    /// Linear radiance at the centre of one fully opaque particle at the reference
    /// temperature.
    pub intensity: f32,
    /// Splat radius as a multiple of the SPH support radius d (Fig 2 spans d: 1).
    pub splat_radius_scale: f32,
    /// Colour model of the blackbody table.
    pub brightness: Brightness,
    /// Temperature of unit brightness for `radiometric`, kelvin.
    pub reference_temperature_k: f32,
    /// A particle is fully opaque at this multiple of the rest density ρ0; alpha falls
    /// linearly below it ("alpha from density", §5.2).
    pub full_alpha_density_ratio: f32,
    /// Heat shimmer.
    pub shimmer: Shimmer,
    /// Background.
    pub background: Background,
    /// Resolution of the splat buffers relative to the frame. 1 splats every pixel, as
    /// the paper does; 0.5 (the default, an extension) splats at half resolution and
    /// upsamples bilinearly, about twice as fast for the same light (the test
    /// `half_resolution_splats_match_full` bounds the difference).
    pub resolution_scale: f32,
    /// What to draw.
    pub view: View,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            // The whole flame in view: the paper's flame reaches 1.18 m (99 % of its
            // particles under 0.98 m, `render --format ply` of scenes/flame-paper.toml,
            // frames 100..180); the view spans -0.28 to 1.48 m at the flame.
            camera: Camera {
                position: Vec3::new(0.0, 0.6, 2.8),
                look_at: Vec3::new(0.0, 0.6, 0.0),
                up: Vec3::Y,
                projection: Projection::Perspective { fov_y_deg: 35.0 },
            },
            intensity: 0.35,
            splat_radius_scale: 1.0,
            brightness: Brightness::Radiometric,
            reference_temperature_k: 1900.0,
            full_alpha_density_ratio: 1.0,
            shimmer: Shimmer::default(),
            background: Background::default(),
            resolution_scale: 0.5,
            view: View::Flame,
        }
    }
}

impl RenderSettings {
    /// Every problem with these settings (fields relative to `[flame.render]`).
    pub fn validate(&self) -> Result<(), Vec<Issue>> {
        let mut i = Issues::default();
        // Splat footprints and the shimmer's screen-space offsets assume straight lines.
        self.camera.validate_planar(&mut i, "camera");
        i.range("intensity", self.intensity, 0.0..=1e9);
        i.range_open_low("splat_radius_scale", self.splat_radius_scale, 0.0, 100.0);
        i.range("reference_temperature_k", self.reference_temperature_k, 500.0..=40_000.0);
        i.range_open_low("full_alpha_density_ratio", self.full_alpha_density_ratio, 0.0, 1e6);
        i.range("shimmer.strength_m", self.shimmer.strength_m, 0.0..=10.0);
        i.range_open_low("shimmer.radius_scale", self.shimmer.radius_scale, 0.0, 100.0);
        i.range("resolution_scale", self.resolution_scale, 0.125..=1.0);
        match &self.background {
            Background::Checker { squares_per_height, light, dark } => {
                i.range_open_low("background.squares_per_height", *squares_per_height, 0.0, 1e4);
                i.vector("background.light", &light.to_array(), 1e6);
                i.vector("background.dark", &dark.to_array(), 1e6);
            }
            Background::Sky { zenith, horizon } => {
                i.vector("background.zenith", &zenith.to_array(), 1e6);
                i.vector("background.horizon", &horizon.to_array(), 1e6);
            }
            Background::Image { path } if path.as_os_str().is_empty() => {
                i.push("background.path", "\"\"", "the path of a PNG file")
            }
            _ => {}
        }
        i.into_result()
    }
}

/// The paper's Fig 1 texture: linear sRGB of a blackbody by temperature, precomputed
/// from 0 to 10,000 K every [`BlackbodyLut::STEP_K`] and interpolated linearly.
#[derive(Clone, Debug)]
pub struct BlackbodyLut {
    table: Vec<Vec3>,
}

impl BlackbodyLut {
    /// Table spacing, kelvin.
    pub const STEP_K: f32 = 5.0;
    /// Highest tabulated temperature (Fig 1 spans 1-10,000 K); hotter values clamp.
    pub const MAX_K: f32 = 10_000.0;

    /// Precompute the table for a brightness model.
    pub fn new(brightness: Brightness, reference_temperature_k: f32) -> Self {
        let n = (Self::MAX_K / Self::STEP_K) as usize + 1;
        let y_ref = blackbody_xyz(Observer::Cie1931TwoDegree, f64::from(reference_temperature_k)).y;
        let table = (0..n)
            .into_par_iter()
            .map(|i| {
                let t = f64::from(i as f32 * Self::STEP_K);
                let rgb = match brightness {
                    Brightness::Normalized => blackbody_srgb_normalized(t),
                    Brightness::Radiometric if y_ref > 0.0 => {
                        xyz_to_linear_srgb(blackbody_xyz(Observer::Cie1931TwoDegree, t) / y_ref)
                            .max(DVec3::ZERO)
                    }
                    Brightness::Radiometric => DVec3::ZERO,
                };
                rgb.as_vec3()
            })
            .collect();
        Self { table }
    }

    /// Linear sRGB at `temperature_k` (black at or below 0 K and for NaN).
    #[inline]
    pub fn lookup(&self, temperature_k: f32) -> Vec3 {
        if !(temperature_k > 0.0) {
            return Vec3::ZERO;
        }
        let f = (temperature_k.min(Self::MAX_K)) / Self::STEP_K;
        let i = (f as usize).min(self.table.len() - 2);
        let t = f - i as f32;
        self.table[i].lerp(self.table[i + 1], t)
    }
}

/// One particle prepared for splatting, in splat-buffer pixels.
#[derive(Clone, Copy, Debug)]
struct Splat {
    x: f32,
    y: f32,
    radius: f32,
    color: Vec3,
    shimmer_radius: f32,
    /// Peak background offset of this particle, in frame pixels.
    shimmer_px: f32,
    depth: f32,
}

/// The cameras of a renderer: at the frame's size and at the splat buffers'.
struct Views {
    view: CameraView,
    splat_view: CameraView,
    splat_w: usize,
    splat_h: usize,
}

/// Renders a flame simulation to linear HDR frames.
#[derive(Clone, Debug)]
pub struct FlameRenderer {
    settings: RenderSettings,
    width: usize,
    height: usize,
    view: CameraView,
    splat_view: CameraView,
    splat_w: usize,
    splat_h: usize,
    lut: BlackbodyLut,
    background: Frame,
    splats: Vec<Option<Splat>>,
    bins: Filed<u32>,
    planes: [Plane; 5],
    /// Per splat-buffer row, the columns any splat touched (start..end; empty if none),
    /// so that compositing only works where the flame or its shimmer is.
    spans: Vec<(u32, u32)>,
    /// The output frame, kept between renders.
    frame: Frame,
    /// Per output row, the columns where `frame` may differ from the background (what
    /// the last render wrote); everywhere else it already equals the background, so a
    /// new render only rewrites these columns and its own.
    dirty: Vec<(u32, u32)>,
    /// Distance to the nearest opaque surface per frame pixel, metres (row-major), when
    /// the flame is composed with surfaces ([`FlameRenderer::set_occluder`]).
    occluder: Option<Vec<f32>>,
    /// What the flame is composited over instead of `background`, when it is composed
    /// with other phenomena ([`FlameRenderer::set_background`]).
    behind: Option<Frame>,
}

impl FlameRenderer {
    /// Whether [`FlameRenderer::new`] accepts `settings` at `width × height` (besides
    /// the background image), without allocating any image.
    pub fn check(settings: &RenderSettings, width: usize, height: usize) -> Result<(), RenderError> {
        settings.validate().map_err(InvalidConfig::from)?;
        Self::views(settings, width, height).map(|_| ())
    }

    /// The camera at the frame's size and at the splat buffers' size.
    fn views(settings: &RenderSettings, width: usize, height: usize) -> Result<Views, RenderError> {
        check_size(width, height)?;
        let size = RenderError::Size { width, height };
        let view = settings.camera.view(width, height).ok_or(size.clone())?;
        let splat_w = ((width as f32 * settings.resolution_scale).round() as usize).max(1);
        let splat_h = ((height as f32 * settings.resolution_scale).round() as usize).max(1);
        let splat_view = settings.camera.view(splat_w, splat_h).ok_or(size)?;
        Ok(Views { view, splat_view, splat_w, splat_h })
    }

    /// A renderer for `width × height` frames. `background_image` is used when the
    /// settings ask for an image background (linear RGB, any size: it is stretched).
    pub fn new(
        settings: RenderSettings,
        width: usize,
        height: usize,
        background_image: Option<&Frame>,
    ) -> Result<Self, RenderError> {
        settings.validate().map_err(InvalidConfig::from)?;
        let Views { view, splat_view, splat_w, splat_h } = Self::views(&settings, width, height)?;
        let wanted = matches!(settings.background, Background::Image { .. });
        let background = match image_background(wanted, background_image, width, height)? {
            Some(image) => image,
            None => procedural_background(&settings.background, width, height),
        };
        Ok(Self {
            lut: BlackbodyLut::new(settings.brightness, settings.reference_temperature_k),
            settings,
            width,
            height,
            view,
            splat_view,
            splat_w,
            splat_h,
            background,
            splats: Vec::new(),
            bins: Filed::default(),
            planes: std::array::from_fn(|_| Plane::new(splat_w, splat_h)),
            spans: vec![(0, 0); splat_h],
            frame: Frame::new(width, height),
            dirty: vec![(0, width as u32); height],
            occluder: None,
            behind: None,
        })
    }

    /// Composite the next renders over `behind` (a frame of this renderer's size, e.g.
    /// the rest of a shot) instead of the settings' background; the shimmer distorts it.
    /// A frame of another size is refused.
    pub fn set_background(&mut self, behind: &Frame) -> Result<(), RenderError> {
        if (behind.width(), behind.height()) != (self.width, self.height) {
            return Err(RenderError::Size { width: behind.width(), height: behind.height() });
        }
        match &mut self.behind {
            Some(b) => b.clone_from(behind),
            None => self.behind = Some(behind.clone()),
        }
        self.dirty.fill((0, self.width as u32));
        Ok(())
    }

    /// Hide what lies behind opaque surfaces in the next renders: `depth` holds the
    /// distance along the view direction to the nearest surface per frame pixel, metres
    /// (row-major, +∞ where none; `None`: no surfaces). A splat is kept or hidden whole,
    /// by its centre: a splat spans a few pixels, so a flame cut by a surface's edge
    /// is cut to within a splat's radius. A depth map of another size is refused.
    pub fn set_occluder(&mut self, depth: Option<&[f32]>) -> Result<(), RenderError> {
        match depth {
            Some(d) if d.len() != self.width * self.height => {
                Err(RenderError::Size { width: self.width, height: self.height })
            }
            Some(d) => {
                let buf = self.occluder.get_or_insert_with(Vec::new);
                buf.clear();
                buf.extend_from_slice(d);
                Ok(())
            }
            None => {
                self.occluder = None;
                Ok(())
            }
        }
    }

    /// The flame's light alone in the last render (the splats upsampled to the frame,
    /// without the background or its shimmer).
    pub fn emission(&self) -> Frame {
        let (w, h) = (self.width, self.height);
        let up = Upsampling::new((w, h), (self.splat_w, self.splat_h));
        let mut out = Frame::new(w, h);
        let mut tmp = [(); 5].map(|_| vec![0.0f32; up.sw]);
        for y in 0..h {
            let (y0, y1, ty) = up.source_rows(y);
            for (p, t) in tmp.iter_mut().enumerate().take(3) {
                let r0 = &self.planes[p].data()[y0 * up.sw..(y0 + 1) * up.sw];
                let r1 = &self.planes[p].data()[y1 * up.sw..(y1 + 1) * up.sw];
                for ((t, &a), &b) in t.iter_mut().zip(r0).zip(r1) {
                    *t = a + (b - a) * ty;
                }
            }
            for x in 0..w {
                let v = up.at(&tmp, x);
                out.set_pixel(x, y, Vec3::new(v[0], v[1], v[2]));
            }
        }
        out
    }

    /// The flame as one point light, for lighting what is around it: where its light is
    /// (the particles' positions weighted by their luminance) and its radiant intensity
    /// in the frame's units of radiance times square metres (each particle's splat
    /// radiance over its footprint, (1 - r²/R²)³ integrating to πR²/4, summed as if no
    /// splat hid another). `None` when nothing glows.
    pub fn light(&self, p: &Particles, config: &FlameConfig) -> Option<(Vec3, Vec3)> {
        let s = &self.settings;
        let r = config.sph.support_radius_m * s.splat_radius_scale;
        let area = std::f64::consts::PI * f64::from(r * r) / 4.0;
        let full_alpha = config.sph.rest_density_kg_m3 * s.full_alpha_density_ratio;
        let (mut at, mut weight, mut total) = (glam::DVec3::ZERO, 0.0f64, glam::DVec3::ZERO);
        for ((x, &t), &rho) in p.position_m.iter().zip(&p.temperature_k).zip(&p.density_kg_m3) {
            let alpha = (rho / full_alpha).clamp(0.0, 1.0);
            let c = (self.lut.lookup(t) * (s.intensity * alpha)).as_dvec3();
            let l = c.x + c.y + c.z;
            at += x.as_dvec3() * l;
            weight += l;
            total += c * area;
        }
        (weight > 0.0).then(|| ((at / weight).as_vec3(), total.as_vec3()))
    }

    /// The settings.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// The blackbody table the particles are coloured with.
    pub fn lut(&self) -> &BlackbodyLut {
        &self.lut
    }

    /// The camera prepared for the output frame.
    pub fn view(&self) -> &CameraView {
        &self.view
    }

    /// The settings' background (before shimmer); what the flame is composited over
    /// unless [`FlameRenderer::set_background`] gave another.
    pub fn background(&self) -> &Frame {
        &self.background
    }

    /// The frame of the last [`FlameRenderer::render`] (black before the first).
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// Render the simulation's current state. The frame is the renderer's own buffer,
    /// reused from frame to frame (clone it to keep it).
    pub fn render(&mut self, sim: &FlameSim) -> &Frame {
        self.render_particles(sim.particles(), sim.config())
    }

    /// Render particles simulated with `config` (its support radius and rest density
    /// set the splat size and the alpha scale).
    pub fn render_particles(&mut self, p: &Particles, config: &FlameConfig) -> &Frame {
        match self.settings.view {
            View::Flame => {
                self.prepare_splats(p, config);
                self.bin_splats();
                self.splat_bands();
                self.composite();
            }
            View::Density => self.render_density(p, config),
        }
        &self.frame
    }

    /// Project particles and compute their colours (in parallel, order-preserving).
    fn prepare_splats(&mut self, p: &Particles, config: &FlameConfig) {
        let s = &self.settings;
        let d = config.sph.support_radius_m * s.splat_radius_scale;
        let full_alpha = config.sph.rest_density_kg_m3 * s.full_alpha_density_ratio;
        let shimmer = if s.shimmer.enabled { s.shimmer.strength_m } else { 0.0 };
        let shimmer_scale = s.shimmer.radius_scale;
        let (view, lut, intensity) = (&self.splat_view, &self.lut, s.intensity);
        let frame_per_splat_px = self.width as f32 / self.splat_w as f32;
        let (w, h) = (self.splat_w as f32, self.splat_h as f32);
        let (occluder, frame_w) = (self.occluder.as_deref(), self.width);
        let hidden = |x_px: f32, y_px: f32, depth: f32| {
            occluder.is_some_and(|d| {
                let (fx, fy) = (x_px * frame_per_splat_px, y_px * frame_per_splat_px);
                let inside = fx >= 0.0 && fy >= 0.0 && (fx as usize) < frame_w;
                let at = fy as usize * frame_w + fx as usize;
                inside && at < d.len() && d[at] < depth
            })
        };
        p.position_m
            .par_iter()
            .zip(p.temperature_k.par_iter())
            .zip(p.density_kg_m3.par_iter())
            .map(|((&x, &t), &rho)| {
                let pr = view.project(x)?;
                let radius = d * pr.px_per_m;
                let reach = radius * shimmer_scale.max(1.0);
                if pr.x_px + reach < 0.0
                    || pr.y_px + reach < 0.0
                    || pr.x_px - reach > w
                    || pr.y_px - reach > h
                {
                    return None;
                }
                if hidden(pr.x_px, pr.y_px, pr.depth) {
                    return None;
                }
                let alpha = (rho / full_alpha).clamp(0.0, 1.0);
                Some(Splat {
                    x: pr.x_px,
                    y: pr.y_px,
                    radius,
                    color: lut.lookup(t) * (intensity * alpha),
                    shimmer_radius: radius * shimmer_scale,
                    shimmer_px: shimmer * pr.px_per_m * frame_per_splat_px,
                    depth: pr.depth,
                })
            })
            .collect_into_vec(&mut self.splats);
    }

    /// File each splat's index under the bands its footprint touches, in particle order.
    fn bin_splats(&mut self) {
        let last = self.splat_h.div_ceil(BAND_ROWS) - 1;
        let splats = &self.splats;
        let span = |i: usize| {
            splats[i].map(|s| {
                let reach = if s.shimmer_px > 0.0 { s.radius.max(s.shimmer_radius) } else { s.radius };
                let y0 = ((s.y - reach).max(0.0) as usize / BAND_ROWS).min(last);
                let y1 = ((s.y + reach).max(0.0) as usize / BAND_ROWS).min(last);
                (y0 as u32, y1 as u32)
            })
        };
        self.bins.refile(last + 1, splats.len(), span, |i| i as u32);
    }

    /// Accumulate flame radiance (Fig 2 profile) and refraction offsets (Fig 3
    /// gradient) band by band.
    fn splat_bands(&mut self) {
        let w = self.splat_w;
        let chunk = BAND_ROWS * w;
        let (splats, bins) = (&self.splats, &self.bins);
        par_chunks5(&mut self.planes, chunk).zip(self.spans.par_chunks_mut(BAND_ROWS)).enumerate().for_each(
            |(band, ([r, g, b, ox, oy], spans))| {
                let row0 = band * BAND_ROWS;
                let rows = r.len() / w;
                let mut out =
                    BandBuffers { w, row0, rows, r, g, b, ox, oy, spans, dx: Vec::new(), lanes: true };
                out.clear();
                for &i in bins.band(band) {
                    if let Some(s) = &splats[i as usize] {
                        out.splat(s);
                    }
                }
            },
        );
    }

    /// Distort the background by the offsets and add the flame, row by row; rows and
    /// columns no splat touched are a plain copy of the background (written only where
    /// the previous frame had something else there).
    fn composite(&mut self) {
        let w = self.width;
        let up = Upsampling::new((w, self.height), (self.splat_w, self.splat_h));
        let sw = up.sw;
        let planes = &self.planes;
        let spans = &self.spans;
        let bg = self.behind.as_ref().unwrap_or(&self.background);
        let [o0, o1, o2] = self.frame.planes_mut();
        o0.data_mut()
            .par_chunks_mut(w)
            .zip(o1.data_mut().par_chunks_mut(w))
            .zip(o2.data_mut().par_chunks_mut(w))
            .zip(self.dirty.par_iter_mut())
            .enumerate()
            .for_each_init(
                || [(); 5].map(|_| vec![0.0f32; sw]),
                |tmp, (y, (((c0, c1), c2), dirty))| {
                    // Restore the background where the last frame wrote.
                    let (d_lo, d_hi) = (dirty.0 as usize, dirty.1 as usize);
                    if d_lo < d_hi {
                        let row = y * w + d_lo..y * w + d_hi;
                        c0[d_lo..d_hi].copy_from_slice(&bg.c0.data()[row.clone()]);
                        c1[d_lo..d_hi].copy_from_slice(&bg.c1.data()[row.clone()]);
                        c2[d_lo..d_hi].copy_from_slice(&bg.c2.data()[row]);
                    }
                    *dirty = (0, 0);
                    let (y0, y1, ty) = up.source_rows(y);
                    let Some((lo, hi)) = touched(spans[y0], spans[y1]) else { return };
                    let (x_lo, x_hi) = up.columns_reading(lo, hi);
                    *dirty = (x_lo as u32, x_hi as u32);
                    if x_lo >= x_hi {
                        return;
                    }
                    // Vertical pass over every source column those outputs read (the
                    // splat planes are zero outside the touched span).
                    let (s_lo, s_hi) = up.columns_read(x_lo, x_hi);
                    for (p, t) in tmp.iter_mut().enumerate() {
                        let r0 = &planes[p].data()[y0 * sw + s_lo..y0 * sw + s_hi];
                        let r1 = &planes[p].data()[y1 * sw + s_lo..y1 * sw + s_hi];
                        for ((t, &a), &b) in t[s_lo..s_hi].iter_mut().zip(r0).zip(r1) {
                            *t = a + (b - a) * ty;
                        }
                    }
                    for x in x_lo..x_hi {
                        let v = up.at(tmp, x);
                        if v[3] != 0.0 || v[4] != 0.0 {
                            let c = bg.sample_bilinear(x as f32 + 0.5 + v[3], y as f32 + 0.5 + v[4]);
                            (c0[x], c1[x], c2[x]) = (c.x, c.y, c.z);
                        }
                        c0[x] += v[0];
                        c1[x] += v[1];
                        c2[x] += v[2];
                    }
                },
            );
    }

    /// Fig 7: particles as squares, coloured from blue (ρ = 0) to red (ρ ≥ 2ρ0), painted
    /// far to near.
    fn render_density(&mut self, p: &Particles, config: &FlameConfig) {
        self.prepare_splats(p, config);
        // The whole frame is redrawn: mark it all as differing from the background.
        self.dirty.fill((0, self.width as u32));
        let out = &mut self.frame;
        let mut order: Vec<(f32, u32)> =
            self.splats.iter().enumerate().filter_map(|(i, s)| s.map(|s| (s.depth, i as u32))).collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for plane in out.planes_mut() {
            plane.clear();
        }
        let scale = self.width as f32 / self.splat_w as f32;
        let rho0 = config.sph.rest_density_kg_m3;
        for (_, i) in order {
            let Some(s) = self.splats[i as usize] else { continue };
            let t = (p.density_kg_m3[i as usize] / (2.0 * rho0)).clamp(0.0, 1.0);
            let color = Vec3::new(t, 0.15, 1.0 - t);
            let half = (0.5 * s.radius * scale).max(0.5);
            let (cx, cy) = (s.x * scale, s.y * scale);
            let x0 = (cx - half).max(0.0) as usize;
            let y0 = (cy - half).max(0.0) as usize;
            let x1 = ((cx + half).max(0.0) as usize).min(self.width - 1);
            let y1 = ((cy + half).max(0.0) as usize).min(self.height - 1);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    out.set_pixel(x, y, color);
                }
            }
        }
    }
}

/// The columns two source rows' splats touched, `a` and `b` (start, end; empty when
/// start ≥ end): the span covering both, or `None` when neither touched any.
#[inline]
fn touched(a: (u32, u32), b: (u32, u32)) -> Option<(usize, usize)> {
    let (lo, hi) = match (a.0 < a.1, b.0 < b.1) {
        (true, true) => (a.0.min(b.0), a.1.max(b.1)),
        (true, false) => a,
        (false, true) => b,
        (false, false) => return None,
    };
    Some((lo as usize, hi as usize))
}

/// How the splat planes (`sw × sh` px) map onto the `w`-wide frame: bilinear
/// upsampling with the taps clamped at the edges, or one to one when the sizes match.
struct Upsampling {
    w: usize,
    sw: usize,
    sh: usize,
    same: bool,
    /// Source pixels per output pixel along x and y.
    kx: f32,
    ky: f32,
    /// Bilinear taps per output column: (x0, x1, weight of x1); none when `same`.
    taps: Vec<(u32, u32, f32)>,
}

impl Upsampling {
    /// From splat planes of `(sw, sh)` px to a frame of `(w, h)` px.
    fn new((w, h): (usize, usize), (sw, sh): (usize, usize)) -> Self {
        let same = sw == w && sh == h;
        let (kx, ky) = (sw as f32 / w as f32, sh as f32 / h as f32);
        let taps = (0..if same { 0 } else { w })
            .map(|x| {
                let fx = ((x as f32 + 0.5) * kx - 0.5).clamp(0.0, (sw - 1) as f32);
                let x0 = fx as usize;
                (x0 as u32, (x0 + 1).min(sw - 1) as u32, fx - x0 as f32)
            })
            .collect();
        Self { w, sw, sh, same, kx, ky, taps }
    }

    /// Source rows of output row `y` and the weight of the second (bilinear in y,
    /// clamped at the edges).
    #[inline]
    fn source_rows(&self, y: usize) -> (usize, usize, f32) {
        if self.same {
            (y, y, 0.0)
        } else {
            let fy = ((y as f32 + 0.5) * self.ky - 0.5).clamp(0.0, (self.sh - 1) as f32);
            let y0 = fy as usize;
            (y0, (y0 + 1).min(self.sh - 1), fy - y0 as f32)
        }
    }

    /// Output columns whose bilinear footprint meets the source columns `lo..hi`.
    #[inline]
    fn columns_reading(&self, lo: usize, hi: usize) -> (usize, usize) {
        if self.same {
            (lo, hi)
        } else {
            (
                ((lo as f32 - 1.0) / self.kx).max(0.0) as usize,
                (((hi as f32 + 1.0) / self.kx) as usize + 1).min(self.w),
            )
        }
    }

    /// Source columns the output columns `x_lo..x_hi` (not empty) read.
    #[inline]
    fn columns_read(&self, x_lo: usize, x_hi: usize) -> (usize, usize) {
        if self.same {
            (x_lo, x_hi)
        } else {
            (self.taps[x_lo].0 as usize, self.taps[x_hi - 1].1 as usize + 1)
        }
    }

    /// The five planes at output column `x`, from the source row blended vertically
    /// into `tmp`.
    #[inline]
    fn at(&self, tmp: &[Vec<f32>; 5], x: usize) -> [f32; 5] {
        if self.same {
            std::array::from_fn(|p| tmp[p][x])
        } else {
            let (x0, x1, tx) = self.taps[x];
            let (x0, x1) = (x0 as usize, x1 as usize);
            std::array::from_fn(|p| tmp[p][x0] + (tmp[p][x1] - tmp[p][x0]) * tx)
        }
    }
}

/// Mutable views of one band of the five splat planes.
struct BandBuffers<'a> {
    w: usize,
    row0: usize,
    rows: usize,
    r: &'a mut [f32],
    g: &'a mut [f32],
    b: &'a mut [f32],
    ox: &'a mut [f32],
    oy: &'a mut [f32],
    spans: &'a mut [(u32, u32)],
    /// Horizontal offsets from the splat centre of the columns it covers (reused).
    dx: Vec<f32>,
    /// Stamp in vectors of [`LANES`] where a row allows (false only to test the scalar
    /// loop against them).
    lanes: bool,
}

impl BandBuffers<'_> {
    fn clear(&mut self) {
        for buf in [&mut *self.r, &mut *self.g, &mut *self.b, &mut *self.ox, &mut *self.oy] {
            buf.fill(0.0);
        }
        self.spans.fill((0, 0));
    }

    /// Prepare the disk at (`x`, `y`) with `radius`: the band-local rows it touches and
    /// the first column of `self.dx`, which holds (column centre - x) for its columns.
    ///
    /// Every row then covers the disk's full bounding box: the profiles are exactly zero
    /// outside the disk (they clamp at 0), and a loop over a fixed width is much cheaper
    /// than finding each row's chord (a square root and rounding per row), about twice
    /// as fast overall for the small splats of a flame (measured at 10,000 particles).
    /// For the same reason the columns are widened to whole groups of [`LANES`] (moved
    /// left at the buffer's right edge) whenever the row is that wide, so every row is
    /// stamped in full vectors; the extra columns add exact zeros.
    fn disk(&mut self, x: f32, y: f32, radius: f32) -> (std::ops::Range<usize>, usize) {
        // Conservative integer bounds by truncation (no libm floor/ceil on the hot path):
        // one extra row or column at most, where the profile is exactly zero.
        let top = (y - radius).max(self.row0 as f32) as usize;
        let bottom = (((y + radius).max(0.0) as usize) + 2).min(self.row0 + self.rows);
        let rows = top.max(self.row0) - self.row0..bottom.max(top) - self.row0;
        let left = ((x - radius).max(0.0) as usize).min(self.w);
        let right = ((((x + radius).max(0.0) as usize) + 2).min(self.w)).max(left);
        if left < right {
            let cols = left..right;
            for ly in rows.clone() {
                self.touch(ly, &cols);
            }
        }
        let wide = (right - left).next_multiple_of(LANES);
        let (start, end) = if self.lanes && left < right && wide <= self.w {
            let start = left.min(self.w - wide);
            (start, start + wide)
        } else {
            (left, right)
        };
        // Written in place (no pushes), so the loop vectorises; columns are below 2³¹,
        // and as i32 they convert to f32 in one instruction (as usize they do not, on
        // x86-64), to the same value.
        self.dx.resize(end - start, 0.0);
        for (c, d) in (start as i32..).zip(self.dx.iter_mut()) {
            *d = c as f32 + 0.5 - x;
        }
        (rows, start)
    }

    /// Record that columns `cols` of band-local row `ly` were touched.
    fn touch(&mut self, ly: usize, cols: &std::ops::Range<usize>) {
        let s = &mut self.spans[ly];
        let (a, b) = (cols.start as u32, cols.end as u32);
        *s = if s.0 < s.1 { (s.0.min(a), s.1.max(b)) } else { (a, b) };
    }

    /// Add one particle: its flame profile and, if enabled, its refraction offsets, in
    /// one pass when both footprints have the same radius (the paper's textures of Figs
    /// 2 and 3 are the same size), else in two.
    fn splat(&mut self, s: &Splat) {
        let shimmer = s.shimmer_px > 0.0;
        if shimmer && s.shimmer_radius == s.radius {
            self.stamp::<true, true>(s, s.radius);
        } else {
            self.stamp::<true, false>(s, s.radius);
            if shimmer {
                self.stamp::<false, true>(s, s.shimmer_radius);
            }
        }
    }

    /// Stamp one particle's disk of `radius` into the band:
    /// - `FLAME` (Fig 2): radiance × (1 - r²/R²)³, the poly6 profile normalised to 1 at
    ///   the centre;
    /// - `SHIMMER` (Fig 3): the refraction direction, the poly6 gradient profile
    ///   (r/R)(1 - r²/R²)² pointing away from the particle (light bends towards the
    ///   denser, cooler air), normalised to a peak of 1 and scaled to `shimmer_px`.
    fn stamp<const FLAME: bool, const SHIMMER: bool>(&mut self, s: &Splat, radius: f32) {
        let r2 = radius * radius;
        if !(r2 > 0.0) {
            return;
        }
        let inv_r2 = 1.0 / r2;
        let scale = s.shimmer_px / (GRADIENT_PROFILE_MAX * radius);
        let (cr, cg, cb) = (s.color.x, s.color.y, s.color.z);
        let (rows, left) = self.disk(s.x, s.y, radius);
        for ly in rows {
            let dy = (self.row0 + ly) as f32 + 0.5 - s.y;
            let dy2 = dy * dy;
            let at = ly * self.w + left;
            let dx = &self.dx[..];
            let n = dx.len();
            let cols = at..at + n;
            let (r, g, b) = (
                &mut self.r[cols.clone()][..n],
                &mut self.g[cols.clone()][..n],
                &mut self.b[cols.clone()][..n],
            );
            let (ox, oy) = (&mut self.ox[cols.clone()][..n], &mut self.oy[cols][..n]);
            if self.lanes && n.is_multiple_of(LANES) {
                // The same arithmetic as the scalar loop below, lane by lane (no fused
                // multiply-adds), so both give the same bits.
                let (one, zero) = (f32x8::splat(1.0), f32x8::splat(0.0));
                let (dy2v, dyv, inv_r2v, scalev) =
                    (f32x8::splat(dy2), f32x8::splat(dy), f32x8::splat(inv_r2), f32x8::splat(scale));
                let (crv, cgv, cbv) = (f32x8::splat(cr), f32x8::splat(cg), f32x8::splat(cb));
                for k in (0..n).step_by(LANES) {
                    let d = load(&dx[k..]);
                    let t = (one - (d * d + dy2v) * inv_r2v).max(zero);
                    let t2 = t * t;
                    if FLAME {
                        let wgt = t2 * t;
                        add(&mut r[k..], wgt * crv);
                        add(&mut g[k..], wgt * cgv);
                        add(&mut b[k..], wgt * cbv);
                    }
                    if SHIMMER {
                        let sw = t2 * scalev;
                        add(&mut ox[k..], sw * d);
                        add(&mut oy[k..], sw * dyv);
                    }
                }
                continue;
            }
            for k in 0..n {
                let t = 1.0 - (dx[k] * dx[k] + dy2) * inv_r2;
                let t = if t > 0.0 { t } else { 0.0 };
                let t2 = t * t;
                if FLAME {
                    let wgt = t2 * t;
                    r[k] += wgt * cr;
                    g[k] += wgt * cg;
                    b[k] += wgt * cb;
                }
                if SHIMMER {
                    let sw = t2 * scale;
                    ox[k] += sw * dx[k];
                    oy[k] += sw * dy;
                }
            }
        }
    }
}

impl phenomena_core::phenomenon::Renderer<FlameSim> for FlameRenderer {
    fn render(&mut self, sim: &FlameSim) -> &Frame {
        FlameRenderer::render(self, sim)
    }

    fn frame(&self) -> &Frame {
        FlameRenderer::frame(self)
    }
}

/// A built-in background at the frame size.
fn procedural_background(bg: &Background, width: usize, height: usize) -> Frame {
    let mut f = Frame::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let c = match bg {
                Background::Black | Background::Image { .. } => Vec3::ZERO,
                Background::Checker { squares_per_height, light, dark } => {
                    let size = height as f32 / squares_per_height;
                    let (i, j) = ((x as f32 / size) as i64, (y as f32 / size) as i64);
                    if (i + j) % 2 == 0 { *light } else { *dark }
                }
                Background::Sky { zenith, horizon } => {
                    horizon.lerp(*zenith, 1.0 - (y as f32 + 0.5) / height as f32)
                }
            };
            f.set_pixel(x, y, c);
        }
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lut_matches_direct_evaluation() {
        let lut = BlackbodyLut::new(Brightness::Normalized, 1900.0);
        for t in [800.0_f32, 1234.5, 1900.0, 6500.0, 9999.0] {
            let direct = blackbody_srgb_normalized(f64::from(t)).as_vec3();
            // Linear interpolation over 5 K steps: the colour changes by < 1e-3 per K
            // here, so the error is far below 1e-3.
            assert!((lut.lookup(t) - direct).abs().max_element() < 1e-3, "{t}");
        }
        assert_eq!(lut.lookup(0.0), Vec3::ZERO);
        assert_eq!(lut.lookup(f32::NAN), Vec3::ZERO);
        assert!(lut.lookup(1e9).is_finite());
    }

    #[test]
    fn radiometric_lut_brightens_with_temperature() {
        let lut = BlackbodyLut::new(Brightness::Radiometric, 1900.0);
        let y = |t: f32| lut.lookup(t).dot(Vec3::new(0.2126, 0.7152, 0.0722));
        assert!((y(1900.0) - 1.0).abs() < 0.02);
        assert!(y(1000.0) < 0.01 * y(1900.0));
        assert!(y(3000.0) > 10.0 * y(1900.0));
    }

    #[test]
    fn vector_stamps_equal_the_scalar_loop() {
        // Splats of many radii and positions, some past the left and right edges and
        // some wider than the band, stamped into one band with and without the
        // eight-wide rows. The vector rows do the scalar loop's arithmetic lane by lane,
        // so every value is equal (== also equates the +0 and -0 that adding an exact
        // zero may leave in the widened columns).
        let (w, rows) = (83usize, BAND_ROWS);
        let mut planes: [[Vec<f32>; 5]; 2] =
            std::array::from_fn(|_| std::array::from_fn(|_| vec![0.0; w * rows]));
        let mut spans = [vec![(0u32, 0u32); rows], vec![(0u32, 0u32); rows]];
        let mut rng = phenomena_core::rng::Stream::new(9, phenomena_core::rng::Purpose::named("test"), 0);
        let splats: Vec<Splat> = (0..400)
            .map(|_| {
                let radius = 0.3 + 30.0 * rng.next_f32().powi(2);
                Splat {
                    x: -10.0 + (w as f32 + 20.0) * rng.next_f32(),
                    y: 32.0 - 8.0 + 32.0 * rng.next_f32(),
                    radius,
                    color: Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()),
                    shimmer_radius: radius * (0.5 + rng.next_f32()),
                    shimmer_px: if rng.next_f32() < 0.2 { 0.0 } else { 3.0 * rng.next_f32() },
                    depth: 1.0,
                }
            })
            .collect();
        let mut vector_rows = 0;
        for (k, (p, sp)) in planes.iter_mut().zip(spans.iter_mut()).enumerate() {
            let [r, g, b, ox, oy] = p;
            let mut out =
                BandBuffers { w, row0: 32, rows, r, g, b, ox, oy, spans: sp, dx: Vec::new(), lanes: k == 0 };
            for s in &splats {
                out.splat(s);
                if k == 0 && out.dx.len().is_multiple_of(LANES) && !out.dx.is_empty() {
                    vector_rows += 1;
                }
            }
        }
        assert!(vector_rows > 300, "most splats take the vector rows ({vector_rows})");
        for (c, (pa, pb)) in planes[0].iter().zip(&planes[1]).enumerate() {
            for (i, (a, b)) in pa.iter().zip(pb).enumerate() {
                assert!(a == b, "plane {c} pixel {i}: {a} vs {b}");
            }
        }
        assert_eq!(spans[0], spans[1]);
        assert!(planes[1][0].iter().any(|&v| v > 0.0) && planes[1][3].iter().any(|&v| v != 0.0));
    }

    #[test]
    fn a_single_splat_has_the_poly6_profile_and_shimmer_points_outwards() {
        let mut settings = RenderSettings {
            background: Background::Black,
            brightness: Brightness::Normalized,
            intensity: 1.0,
            resolution_scale: 1.0,
            ..Default::default()
        };
        settings.camera.projection = Projection::Orthographic { height_m: 1.0 };
        settings.camera.position = Vec3::new(0.0, 0.0, 2.0);
        settings.camera.look_at = Vec3::ZERO;
        let config = FlameConfig::default();
        let mut r = FlameRenderer::new(settings, 101, 101, None).unwrap();
        let d = config.sph.support_radius_m;
        let p = Particles {
            position_m: vec![Vec3::ZERO],
            temperature_k: vec![6500.0],
            density_kg_m3: vec![config.sph.rest_density_kg_m3],
            ..Default::default()
        };
        let f = r.render_particles(&p, &config);
        let centre = f.pixel(50, 50).max_element();
        assert!((centre - 1.0).abs() < 1e-6, "{centre}");
        // At r = d/2 (101 px per metre): (1 - 1/4)³ = 0.421875 of the centre.
        let px = (0.5 * d * 101.0) as usize;
        let q = (px as f32 / (d * 101.0)).powi(2);
        let expect = (1.0 - q).powi(3);
        assert!((f.pixel(50 + px, 50).max_element() - expect).abs() < 1e-5);
        // Offsets: right of the centre they point right, above it they point up.
        let [.., ox, oy] = &r.planes;
        assert!(ox.get(52, 50) > 0.0 && ox.get(48, 50) < 0.0);
        assert!(oy.get(50, 48) < 0.0 && oy.get(50, 52) > 0.0);
        assert_eq!(ox.get(0, 0), 0.0);
    }
}
