//! The sky view: the aurora as a camera sees it (§2.4 and the physical extension).
//!
//! Geometry: the x-z plane of the simulation lies at the top of the atmosphere, centred
//! over the origin (world x west, z north, y altitude, all km, flat Earth: right-handed,
//! so a camera looking north has +x on its left); each particle
//! is the foot of a field line that runs down along B (vertical, or tilted by
//! `field_tilt_deg` towards `field_azimuth_deg`).
//!
//! Emission points per particle come from one of two models:
//! - `paper` (§2.4.1-2.4.2, [`crate::fall`]): the particle falls by eq 2.21-2.22 and each
//!   collision may emit one line; every emission counts the emission weight × the
//!   attenuation of eq 2.27 (a 630.0 nm one lands where its O(¹D) diffused to);
//! - `physical` (default, [`crate::deposition`]): each line's emission points are drawn
//!   from that line's volume emission profile by inverse CDF along the field line, each
//!   carrying an equal share of the line's column brightness over the particle's
//!   footprint, so the image is in rayleighs.
//!
//! Each line has its own image. The thesis splats every emission with a Gaussian of a
//! per-line σ (eq 2.28); here every emission is deposited (bilinear) and each line's
//! image is blurred once with that Gaussian, which is the same sum (test
//! `deposit_then_blur_is_the_sum_of_splats`). The five images become XYZ with the
//! colour-matching values of the lines (Table 2.1 in `paper` mode, the CIE 2015 observer
//! otherwise; eq 2.29 with K = 683 lm/W) and then linear sRGB (eq 2.30).
//!
//! Determinism: in `paper` mode each particle's random stream is keyed by (seed, frame,
//! particle id); in `physical` mode its sample offsets by (seed, frame) and its place in
//! the store ([`SkyRenderer::set_sample_salt`] adds a salt to both); emissions are
//! produced per fixed chunk of particles and deposited per fixed band of rows, chunk by
//! chunk in order, so the result does not depend on the thread count.

use glam::{DVec3, Vec3};
use phenomena_core::camera::{Camera, CameraView, NEAR_M, Pinhole, Projection};
use phenomena_core::clock::SharedClock;
use phenomena_core::color::{
    LIGHT_SPEED_M_PER_S, Observer, PLANCK_J_S, blackbody_xyz, spectral_line_xyz, xyz_to_linear_srgb,
};
use phenomena_core::image::{Frame, Plane, par_chunks5};
use phenomena_core::phenomenon::{RenderError, check_size, image_background};
use phenomena_core::rng::{Purpose, Stream};
use phenomena_core::validate::{InvalidConfig, Issue, Issues};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wide::f32x8;

use crate::atmosphere::Atmosphere;
use crate::deposition::{AltitudeSampler, ColumnModel, Precipitation, Yields};
use crate::emission::{Line, xyz_to_rgb_eq_2_30};
use crate::fall::{AirTable, FallPool, Falls, PaperEmission, PaperFall, attenuation, paper_emissions};
use crate::night::{self, Airglow, Site};
use crate::sim::AuroraSim;
use crate::small_scale::Prepared;

mod tiles;

const EMIT: Purpose = Purpose::named("aurora.sky.emit");
/// Mixing a salt into the frame's key ([`SkyRenderer::set_sample_salt`]).
const SALT: Purpose = Purpose::named("aurora.sky.salt");
/// The per-frame offsets of the physical model's systematic samples.
const EMIT_OFFSETS: Purpose = Purpose::named("aurora.sky.emit-offsets");
/// The key of the paper mode's pool of falls, from the seed and the salt.
const FALL_POOL_KEY: Purpose = Purpose::named("aurora.sky.fall-pool-key");

/// The small-scale motion of `sim`'s current frame ([`crate::small_scale`]), if on.
pub fn small_scale_now(sim: &AuroraSim) -> Option<Prepared> {
    let config = sim.config();
    let frame = sim.frame();
    let time_s = frame as f64 * f64::from(config.motion.time_step_s);
    config.small_scale.at(&sim.animation().shape_at(frame as f32), time_s, sim.seed())
}

/// Which emission and colour model the sky view uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ColourMode {
    /// The thesis's fall and emission (§2.4, [`crate::fall`]), Table 2.1's colours; its
    /// unprinted constants from the physics it cites, or as first read
    /// (`[render.sky.paper]`).
    Paper,
    /// Energy deposition over the NRLMSIS atmosphere, yields and rate-coefficient
    /// quenching, image in rayleighs.
    #[default]
    Physical,
}

/// A value per emission line (TOML keys `n2p391`, `n2p428`, `o557`, `o630`, `n2_670`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerLine {
    /// 391.4 nm.
    pub n2p391: f32,
    /// 427.8 nm.
    pub n2p428: f32,
    /// 557.7 nm.
    pub o557: f32,
    /// 630.0 nm.
    pub o630: f32,
    /// 670.5 nm.
    pub n2_670: f32,
}

impl PerLine {
    /// The values in [`Line::ALL`] order.
    pub fn to_array(self) -> [f32; 5] {
        [self.n2p391, self.n2p428, self.o557, self.o630, self.n2_670]
    }
}

/// Where the camera is. Positions are relative to the point on the ground under the
/// plane's centre; north is +z.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum SkyCamera {
    /// An observer on the ground `distance_km` south of the centre, looking north and up
    /// at `elevation_deg` (perspective; the thesis's view, Table 3.2: 1280 × 720).
    /// Defaults: 250 km, 28°, 60° (the horizon 2° above the bottom edge; the thesis's
    /// framing is 38°, [`SkySettings::thesis`]).
    Ground {
        /// Distance south of the plane's centre, km.
        #[serde(default = "defaults::ground_distance_km")]
        distance_km: f32,
        /// Elevation of the view direction above the horizon, degrees.
        #[serde(default = "defaults::ground_elevation_deg")]
        elevation_deg: f32,
        /// Vertical field of view, degrees.
        #[serde(default = "defaults::fov_y_deg")]
        fov_y_deg: f32,
    },
    /// A spacecraft at `altitude_km`, `distance_km` south of the centre, looking at the
    /// centre at `look_at_altitude_km`. Defaults: the International Space Station's
    /// 400 km, 1,000 km south, looking at 110 km (where the green line shines), 60°.
    Orbit {
        /// Altitude, km.
        #[serde(default = "defaults::orbit_altitude_km")]
        altitude_km: f32,
        /// Horizontal distance south of the centre, km.
        #[serde(default = "defaults::orbit_distance_km")]
        distance_km: f32,
        /// Altitude of the point looked at, km.
        #[serde(default = "defaults::orbit_look_at_altitude_km")]
        look_at_altitude_km: f32,
        /// Vertical field of view, degrees.
        #[serde(default = "defaults::fov_y_deg")]
        fov_y_deg: f32,
    },
    /// A planetarium dome master: equidistant fisheye on the ground at the centre, zenith
    /// at the image centre, north up.
    Dome {
        /// Field of view across the circle, degrees (default 180: a dome).
        #[serde(default = "defaults::dome_fov_deg")]
        fov_deg: f32,
    },
    /// A 360° × 180° equirectangular panorama on the ground at the centre, north in the
    /// middle (nothing to set).
    Panorama,
    /// Any core camera, in km.
    Custom {
        /// The camera.
        camera: Camera,
    },
}

impl SkyCamera {
    /// The core camera this stands for.
    pub fn camera(&self) -> Camera {
        // Eye 2 m above the ground so the horizon is not at the eye.
        const EYE_KM: f32 = 0.002;
        match *self {
            SkyCamera::Ground { distance_km, elevation_deg, fov_y_deg } => {
                let e = elevation_deg.to_radians();
                let position = Vec3::new(0.0, EYE_KM, -distance_km);
                Camera {
                    position,
                    look_at: position + Vec3::new(0.0, e.sin(), e.cos()) * 100.0,
                    up: Vec3::Y,
                    projection: Projection::Perspective { fov_y_deg },
                }
            }
            SkyCamera::Orbit { altitude_km, distance_km, look_at_altitude_km, fov_y_deg } => Camera {
                position: Vec3::new(0.0, altitude_km, -distance_km),
                look_at: Vec3::new(0.0, look_at_altitude_km, 0.0),
                up: Vec3::Y,
                projection: Projection::Perspective { fov_y_deg },
            },
            SkyCamera::Dome { fov_deg } => Camera {
                position: Vec3::new(0.0, EYE_KM, 0.0),
                look_at: Vec3::new(0.0, 1.0, 0.0),
                up: Vec3::Z,
                projection: Projection::Fisheye { fov_deg },
            },
            SkyCamera::Panorama => Camera {
                position: Vec3::new(0.0, EYE_KM, 0.0),
                look_at: Vec3::new(0.0, EYE_KM, 1.0),
                up: Vec3::Y,
                projection: Projection::Equirectangular,
            },
            SkyCamera::Custom { camera } => camera,
        }
    }
}

impl Default for SkyCamera {
    fn default() -> Self {
        SkyCamera::Ground {
            distance_km: defaults::ground_distance_km(),
            elevation_deg: defaults::ground_elevation_deg(),
            fov_y_deg: defaults::fov_y_deg(),
        }
    }
}

/// What a camera kind's fields default to when the scene file leaves them out (so that
/// `kind = "dome"` alone is a camera, not a refusal for want of `fov_deg`).
mod defaults {
    pub(super) fn ground_distance_km() -> f32 {
        250.0
    }
    pub(super) fn ground_elevation_deg() -> f32 {
        28.0
    }
    pub(super) fn fov_y_deg() -> f32 {
        60.0
    }
    pub(super) fn orbit_altitude_km() -> f32 {
        400.0
    }
    pub(super) fn orbit_distance_km() -> f32 {
        1000.0
    }
    pub(super) fn orbit_look_at_altitude_km() -> f32 {
        110.0
    }
    pub(super) fn dome_fov_deg() -> f32 {
        180.0
    }
}

/// What lies behind the aurora in the sky view.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum SkyBackground {
    /// A black night sky (with the stars and the ground when those are switched on).
    #[default]
    Night,
    /// An image file (sRGB, stretched bilinearly to the frame's size; e.g. a photograph
    /// of a night landscape) under the aurora's light, which is added to it; the caller
    /// loads it and passes it to [`SkyRenderer::new`]. Stars and ground are still drawn
    /// when switched on.
    Image {
        /// Path, relative to the scene file.
        path: std::path::PathBuf,
    },
}

/// Settings of the sky view (`[render.sky]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SkySettings {
    /// Emission and colour model.
    pub mode: ColourMode,
    /// The camera.
    pub camera: SkyCamera,
    /// Altitude of the simulation plane (where falls start and profiles end), km.
    pub top_altitude_km: f32,
    /// Angle of B from the vertical, degrees (0: vertical field lines; the geomagnetic
    /// field at auroral latitudes is about 12° from vertical).
    pub field_tilt_deg: f32,
    /// Direction the field lines lean towards with depth, degrees from north (+z)
    /// towards +x (west).
    pub field_azimuth_deg: f32,
    /// Standard deviation of each line's splat (eq 2.28), pixels at a 1280-pixel-wide
    /// image (scaled with the width).
    pub splat_sigma_px: PerLine,
    /// `physical` mode: emission points per particle, shared among the lines by
    /// their share of the column's colour. A line's m points sit at the altitudes
    /// below which the shares (j + ξ)/m of its column are emitted, j = 0..m, with one
    /// uniform ξ per particle and line (systematic sampling: evenly spaced in the
    /// column), and neighbouring particles' ξ spread evenly over [0, 1) (a Weyl
    /// sequence over the store's cell order, `ColumnOffsets`). A line that emits gets
    /// at least one point, so the sum can pass this by up to the five lines' rounding
    /// (15 gives 17: 1, 3, 11, 1 and 1 for the default precipitation). With 15, scene 2
    /// seen from the ground is closer to a 512-point reference than with 28 independent
    /// offsets, with 40 % fewer points to emit and deposit; close-ups, where few columns
    /// share a pixel, are a little noisier (test `sampling_quality` measures seven views).
    pub points_per_particle: u32,
    /// `physical` mode: the precipitating electrons.
    pub precipitation: Precipitation,
    /// `physical` mode: excitation yields.
    pub yields: Yields,
    /// `physical` mode: each line's image decays with the line's effective lifetime over
    /// frames instead of following the particles at once (630.0 nm lingers ~half a minute).
    pub afterglow: bool,
    /// Draw the stars behind the aurora: the Hipparcos catalogue's, where they stand for
    /// `site` at its time ([`crate::night`]), in the same units as the aurora (default
    /// on, as are `airglow`, `milky_way` and `ground`: [`SkySettings::thesis`] has them
    /// off).
    pub stars: bool,
    /// Faintest star drawn, visual magnitude (default 5.5; the catalogue ends at 6, so
    /// a fainter limit draws the whole catalogue).
    pub star_limiting_magnitude: f32,
    /// Where and when the sky is seen (the stars' positions).
    pub site: Site,
    /// `physical` mode: add the airglow, the night sky's own 557.7, 630.0 nm and OH
    /// light, brighter towards the horizon ([`crate::night`]; not drawn in `paper` mode,
    /// whose image has no physical unit).
    pub airglow: bool,
    /// The airglow's zenith brightness per emission, rayleighs.
    pub airglow_zenith: Airglow,
    /// Draw the Milky Way: the integrated light of its unresolved stars as a band of
    /// five outline levels (d3-celestial's, [`crate::night::milky_way_level`]), where it
    /// stands for `site` at its time, in a 4500 K starlight colour, dimmed by extinction.
    pub milky_way: bool,
    /// The Milky Way's surface brightness in its brightest star clouds (its level 5),
    /// V mag/arcsec²; each level below is 0.625 magnitudes fainter (level 1: 23.5, about
    /// the faint outer band), and outside it nothing.
    pub milky_way_mag_arcsec2: f32,
    /// Draw a dark ground with low hills below the horizon (hides what is behind it).
    pub ground: bool,
    /// `paper` mode: the fall and emission parameters.
    pub paper: PaperFall,
    /// `physical` mode: brightness of 557.7 nm light, kilorayleighs, that makes image
    /// value 1 (the frame is linear sRGB relative to that luminance; the line layers
    /// stay in rayleighs). Moderate aurora is a few kR of green, seen edge-on along a
    /// curtain tens of kR.
    pub white_kilorayleigh: f32,
    /// `paper` mode: image value of one unattenuated 557.7 nm emission landing in a
    /// pixel of a 1280-pixel-wide image (at other widths scaled with the pixel's area, so
    /// a preview is exposed like the final frame; the other lines scale by their
    /// colour-matching values, eq 2.29; line layers count emissions, each weighted by
    /// [`crate::fall::PaperEmission::weight`] and attenuation).
    pub paper_emission_brightness: f32,
    /// Behind the aurora.
    pub background: SkyBackground,
}

/// Spacing, pixels, of the grid of ray directions the night's passes interpolate.
const NIGHT_STEP_PX: usize = 4;

/// Steps of the airglow's table over sin(elevation) from 0 to 1.
const AIRGLOW_STEPS: usize = 1024;

/// Sine of the highest hill (1.5° + 0.8° + 0.5° + 0.3° = 3.1°, and a margin).
const HILLS_TOP_SIN: f32 = 0.0559; // sin 3.2°

/// The ground's horizon at azimuth `azimuth` (radians from north): low hills, 1.5° ±
/// 1.6°, a sum of sines.
#[inline]
fn hills_rad(azimuth: f32) -> f32 {
    (1.5 + 0.8 * (3.0 * azimuth).sin()
        + 0.5 * (7.0 * azimuth + 1.0).sin()
        + 0.3 * (13.0 * azimuth + 2.0).sin())
    .to_radians()
}

/// Width the `paper` mode's exposure and every splat size refer to, pixels.
const REFERENCE_WIDTH_PX: f64 = 1280.0;

/// Default [`SkySettings::paper_emission_brightness`].
const PAPER_EMISSION_BRIGHTNESS: f32 = 0.01;

impl Default for SkySettings {
    fn default() -> Self {
        Self {
            mode: ColourMode::Physical,
            camera: SkyCamera::default(),
            top_altitude_km: 400.0,
            field_tilt_deg: 0.0,
            field_azimuth_deg: 0.0,
            splat_sigma_px: PerLine { n2p391: 1.2, n2p428: 1.2, o557: 1.2, o630: 2.5, n2_670: 1.2 },
            points_per_particle: 15,
            precipitation: Precipitation::default(),
            yields: Yields::default(),
            afterglow: false,
            stars: true,
            star_limiting_magnitude: 5.5,
            site: Site::default(),
            airglow: true,
            airglow_zenith: Airglow::default(),
            milky_way: true,
            milky_way_mag_arcsec2: 21.0,
            ground: true,
            white_kilorayleigh: 20.0,
            paper: PaperFall::default(),
            paper_emission_brightness: PAPER_EMISSION_BRIGHTNESS,
            background: SkyBackground::Night,
        }
    }
}

impl SkySettings {
    /// The thesis's sky (§2.4, Table 3.2): the aurora alone over black (no stars,
    /// airglow or ground), seen from the ground 250 km south, 38° up. With
    /// `[aurora.small_scale] enabled = false` it gives the frames of the thesis scenes
    /// before the night was added; the tests that measure the aurora's own light use it.
    pub fn thesis() -> Self {
        Self {
            stars: false,
            airglow: false,
            milky_way: false,
            ground: false,
            camera: SkyCamera::Ground { distance_km: 250.0, elevation_deg: 38.0, fov_y_deg: 60.0 },
            ..Self::default()
        }
    }

    /// Every problem, with fields relative to `[render.sky]`.
    pub fn validate(&self) -> Result<(), Vec<Issue>> {
        let mut i = Issues::default();
        self.camera.camera().validate(&mut i, "camera");
        match self.camera {
            SkyCamera::Ground { distance_km, elevation_deg, .. } => {
                i.range("camera.distance_km", distance_km, 0.0..=5000.0);
                i.range("camera.elevation_deg", elevation_deg, -89.0..=89.0);
            }
            SkyCamera::Orbit { altitude_km, .. } => {
                i.range("camera.altitude_km", altitude_km, 0.0..=100_000.0)
            }
            _ => {}
        }
        i.range("top_altitude_km", self.top_altitude_km, 100.0..=500.0);
        i.range("field_tilt_deg", self.field_tilt_deg, 0.0..=80.0);
        i.range("field_azimuth_deg", self.field_azimuth_deg, -360.0..=360.0);
        for (line, s) in Line::ALL.iter().zip(self.splat_sigma_px.to_array()) {
            i.range(&format!("splat_sigma_px ({} nm)", line.wavelength_nm()), s, 0.0..=64.0);
        }
        i.count("points_per_particle", u64::from(self.points_per_particle), 5..=10_000);
        self.precipitation.validate(&mut i, "precipitation");
        self.yields.validate(&mut i, "yields");
        self.paper.validate(&mut i, "paper");
        i.range_open_low("white_kilorayleigh", self.white_kilorayleigh, 0.0, 1e6);
        i.range("star_limiting_magnitude", self.star_limiting_magnitude, -2.0..=9.0);
        self.site.validate(&mut i, "site");
        self.airglow_zenith.validate(&mut i, "airglow_zenith");
        i.range("milky_way_mag_arcsec2", self.milky_way_mag_arcsec2, 10.0..=40.0);
        i.range("paper_emission_brightness", self.paper_emission_brightness, 0.0..=1e9);
        if let SkyBackground::Image { path } = &self.background
            && path.as_os_str().is_empty()
        {
            i.push("background.path", "\"\"", "the path of a PNG file");
        }
        i.into_result()
    }

    /// Unit vector along B into the atmosphere, and the horizontal drift per km of descent.
    pub(crate) fn field(&self) -> (DVec3, DVec3) {
        let (tilt, az) =
            (f64::from(self.field_tilt_deg).to_radians(), f64::from(self.field_azimuth_deg).to_radians());
        let drift = DVec3::new(az.sin(), 0.0, az.cos()) * tilt.tan();
        ((drift - DVec3::Y).normalize(), drift)
    }
}

/// One emission projected to the image.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Splat {
    x: f32,
    y: f32,
    weight: f32,
    line: u8,
}

/// Rows per deposit band.
const BAND_ROWS: usize = 8;
/// Particles per emission chunk.
const CHUNK: usize = 1024;

/// Renders the sky view of an [`AuroraSim`].
pub struct SkyRenderer {
    settings: SkySettings,
    width: usize,
    height: usize,
    view: CameraView,
    /// The camera position, km.
    eye: Vec3,
    sigma_px: [f32; 5],
    model: Model,
    /// The current images of the five lines ([`Line::ALL`] order), after the blur (and
    /// the afterglow): rayleighs in `physical` mode.
    lines: [Plane; 5],
    glow_started: bool,
    frame: Frame,
    /// The image behind the aurora at the frame's size, if any.
    background: Option<Frame>,
    timings: SkyTimings,
    clock: SharedClock,
    /// Emit for particles `i` with `i % stride == phase` only, with `stride` times the
    /// weight (stride 1: all).
    stride: usize,
    phase: usize,
    /// Key of the emission's random numbers besides seed and frame
    /// ([`SkyRenderer::set_sample_salt`]).
    salt: u64,
    /// Memory kept between frames: each emission chunk's points filed by band, the
    /// unblurred line images and the blur's intermediate image (a 1280x720 frame of
    /// 120,000 particles at 14 points holds about 27 MB of points; allocated afresh
    /// every frame, their page faults and unmapping cost more than the deposit).
    chunks: Vec<BandedPoints>,
    /// Project the physical mode's points in lanes (false only to test the scalar path
    /// against them).
    lanes: bool,
    fresh: [Plane; 5],
    blur_tmp: Vec<f32>,
    /// Ray directions every [`NIGHT_STEP_PX`] pixels (the view is fixed): the night's
    /// passes interpolate them ([`SkyRenderer::draw_night`]).
    night_dirs: NightGrid,
    /// Each catalogue star to the limiting magnitude: its linear sRGB per unit of
    /// transmission and solid angle (colour × illuminance / white), worked out once.
    star_light: Vec<Vec3>,
    /// [`SkyRenderer::still_night`], worked out at the first frame (empty until then).
    still_night: Vec<Option<Vec3>>,
    /// The runs' tiles of the physical mode's deposit through a perspective camera
    /// (`tiles.rs`), their memory kept between frames.
    tiles: Vec<tiles::Tile>,
    /// Take the tiles' path where it applies (false only to test the banded path
    /// against it).
    tiled: bool,
}

/// Ray directions of the points (i, j) · [`NIGHT_STEP_PX`] of the image.
#[derive(Clone, Debug, Default)]
struct NightGrid {
    w: usize,
    h: usize,
    dirs: Vec<Vec3>,
}

impl NightGrid {
    fn new(view: &CameraView, width: usize, height: usize) -> Self {
        let (w, h) = (width.div_ceil(NIGHT_STEP_PX) + 1, height.div_ceil(NIGHT_STEP_PX) + 1);
        let dirs = (0..w * h)
            .into_par_iter()
            .map(|k| {
                let (x, y) = ((k % w) * NIGHT_STEP_PX, (k / w) * NIGHT_STEP_PX);
                view.ray(x as f32, y as f32).1.normalize_or_zero()
            })
            .collect();
        Self { w, h, dirs }
    }

    /// Grid cell (i, j) and weights (tx, ty) of the pixel centre (x, y).
    #[inline]
    fn at(&self, x: usize, y: usize) -> (usize, usize, f32, f32) {
        let fx = (x as f32 + 0.5) / NIGHT_STEP_PX as f32;
        let fy = (y as f32 + 0.5) / NIGHT_STEP_PX as f32;
        ((fx as usize).min(self.w - 2), (fy as usize).min(self.h - 2), fx.fract(), fy.fract())
    }

    /// `values` (one per grid point) interpolated bilinearly at cell (i, j), (tx, ty).
    #[inline]
    fn lerp<T>(values: &[T], w: usize, (i, j, tx, ty): (usize, usize, f32, f32)) -> T
    where
        T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let top = values[j * w + i] * (1.0 - tx) + values[j * w + i + 1] * tx;
        let bottom = values[(j + 1) * w + i] * (1.0 - tx) + values[(j + 1) * w + i + 1] * tx;
        top * (1.0 - ty) + bottom * ty
    }
}

/// One emission chunk's points, filed by the band of their first row as they are
/// emitted (their second row may spill into the next band: see [`deposit_banded`]).
/// Points entirely outside the image (or with a non-finite weight) are dropped.
#[derive(Default)]
struct BandedPoints {
    bands: Vec<Vec<Splat>>,
    /// One particle's points before projection (altitude km, photons per point, line).
    lanes: Vec<(f32, f32, u8)>,
    height: usize,
    /// Factor on every weight (the preview's particle stride).
    scale: f32,
}

impl BandedPoints {
    /// Empty bands for an image `height` rows tall (their memory kept).
    fn reset(&mut self, height: usize, scale: f32) {
        self.bands.resize_with(height.div_ceil(BAND_ROWS), Vec::new);
        for b in &mut self.bands {
            b.clear();
        }
        (self.height, self.scale) = (height, scale);
    }

    #[inline]
    fn push(&mut self, mut s: Splat) {
        let fy = s.y - 0.5;
        s.weight *= self.scale;
        if !(fy >= -1.0 && fy < self.height as f32 && s.weight.is_finite()) {
            return;
        }
        self.bands[floor_i32(fy).max(0) as usize / BAND_ROWS].push(s);
    }

    /// The points of band `b`, in emission order.
    fn band(&self, b: usize) -> &[Splat] {
        &self.bands[b]
    }

    /// Points over all bands.
    fn len(&self) -> usize {
        self.bands.iter().map(Vec::len).sum()
    }
}

/// Where the last render's time went, ms (0 unless the renderer was given a clock by
/// [`SkyRenderer::set_clock`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SkyTimings {
    /// Emission points: falls or profile sampling, projection, bucketing.
    pub emit_ms: f64,
    /// Deposit into the line images.
    pub deposit_ms: f64,
    /// Per-line Gaussian blur (eq 2.28) and afterglow.
    pub blur_ms: f64,
    /// Line images to linear sRGB.
    pub colour_ms: f64,
    /// Emission points deposited: those whose row touches the image (the banded
    /// path) or whose pixels do (the physical mode's tiles, `sky/tiles.rs`).
    pub points: usize,
}

enum Model {
    /// `pool`: [`Falls::Pooled`]'s falls, drawn at the first frame (and again for another
    /// seed or salt).
    Paper {
        air: AirTable,
        emission: PaperEmission,
        pool: Option<FallPool>,
    },
    Physical {
        column: Box<ColumnModel>,
        sampler: AltitudeSampler,
        points: [u32; 5],
        photons: [f64; 5],
    },
}

impl SkyRenderer {
    /// A renderer for `width × height` images; `background` is the loaded image (linear
    /// RGB, any size: it is stretched to the frame by [`Frame::resized`]) when the
    /// settings ask for one.
    pub fn new(
        settings: SkySettings,
        width: usize,
        height: usize,
        background: Option<&Frame>,
    ) -> Result<Self, RenderError> {
        let view = Self::view(&settings, width, height)?;
        let wanted = matches!(settings.background, SkyBackground::Image { .. });
        let background = image_background(wanted, background, width, height)?;
        let air = Atmosphere::msis21();
        let model = match settings.mode {
            ColourMode::Paper => Model::Paper {
                air: AirTable::new(air),
                emission: PaperEmission::new(air, &settings.paper, &settings.precipitation, &settings.yields),
                pool: None,
            },
            ColourMode::Physical => {
                let column = ColumnModel::new(air, &settings.precipitation, &settings.yields);
                let photons = Line::ALL.map(|l| column.column_photons_cm2_s(l));
                let points = allocate_points(settings.points_per_particle, &photons);
                let sampler = column.altitude_sampler();
                Model::Physical { column: Box::new(column), sampler, points, photons }
            }
        };
        let scale = (width as f64 / REFERENCE_WIDTH_PX) as f32;
        let sigma_px = settings.splat_sigma_px.to_array().map(|s| s * scale);
        let eye = settings.camera.camera().position;
        let night_dirs = NightGrid::new(&view, width, height);
        Ok(Self {
            night_dirs,
            star_light: Vec::new(),
            still_night: Vec::new(),
            tiles: Vec::new(),
            tiled: true,
            settings,
            width,
            height,
            view,
            eye,
            sigma_px,
            model,
            lines: std::array::from_fn(|_| Plane::new(width, height)),
            glow_started: false,
            frame: Frame::new(width, height),
            background,
            timings: SkyTimings::default(),
            clock: SharedClock::default(),
            stride: 1,
            phase: 0,
            salt: 0,
            chunks: Vec::new(),
            lanes: true,
            fresh: std::array::from_fn(|_| Plane::new(width, height)),
            blur_tmp: Vec::new(),
        })
    }

    /// Whether [`SkyRenderer::new`] accepts `settings` at `width × height` (besides the
    /// background image), without building its tables or images.
    pub fn check(settings: &SkySettings, width: usize, height: usize) -> Result<(), RenderError> {
        Self::view(settings, width, height).map(|_| ())
    }

    fn view(settings: &SkySettings, width: usize, height: usize) -> Result<CameraView, RenderError> {
        settings.validate().map_err(InvalidConfig::from)?;
        check_size(width, height)?;
        settings.camera.camera().view(width, height).ok_or(RenderError::Size { width, height })
    }

    /// Time the parts of each render with `clock` (the library reads no clock itself).
    pub fn set_clock(&mut self, clock: SharedClock) {
        self.clock = clock;
    }

    /// The settings.
    pub fn settings(&self) -> &SkySettings {
        &self.settings
    }

    /// The five line images of the last render, in [`Line::ALL`] order (rayleighs in
    /// `physical` mode).
    pub fn line_images(&self) -> &[Plane; 5] {
        &self.lines
    }

    /// Where the last render's time went.
    pub fn timings(&self) -> SkyTimings {
        self.timings
    }

    /// The frame of the last [`SkyRenderer::render`] (linear sRGB; black before it).
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The `physical` mode's column model (`None` in `paper` mode).
    pub fn column_model(&self) -> Option<&ColumnModel> {
        match &self.model {
            Model::Physical { column, .. } => Some(column),
            Model::Paper { .. } => None,
        }
    }

    /// A preview extension (not in the thesis): emit for the particles `i` with
    /// `i % stride == phase` only and weight their emissions `stride` times. The mean of
    /// the `stride` phases' images is the full image (exactly in `paper` mode, tested; in
    /// `physical` mode in expectation: the sample offsets are spread over the subset's
    /// particles, `ColumnOffsets`), so a live preview can cut the emission work
    /// `stride`-fold at the price of noise. Particles are kept in cell order, so one
    /// phase thins each region evenly. Stride 1 (the default) renders every particle; 0
    /// counts as 1 and the phase is taken modulo the stride.
    pub fn set_particle_subset(&mut self, stride: usize, phase: usize) {
        self.stride = stride.max(1);
        self.phase = phase % self.stride;
    }

    /// Draw the emission's random numbers (the physical model's sample offsets, the
    /// paper model's falls) from another independent set, keyed by `salt` (0, the
    /// default, is the set every render uses). The image's expectation is the same, its
    /// noise independent: for measuring noise against a reference, or averaging several
    /// renders of one frame into a cleaner still.
    pub fn set_sample_salt(&mut self, salt: u64) {
        self.salt = salt;
    }

    /// Render the sky over `sim`'s current particles; returns linear sRGB.
    pub fn render(&mut self, sim: &AuroraSim) -> &Frame {
        self.emit_and_deposit(sim);
        let clock = self.clock.clone();
        let t = clock.stopwatch();
        for (plane, sigma) in self.fresh.iter_mut().zip(self.sigma_px) {
            plane.gaussian_blur_with(sigma, &mut self.blur_tmp);
        }
        match (&self.model, self.settings.afterglow && self.glow_started) {
            (Model::Physical { column, .. }, true) => {
                let dt = f64::from(sim.config().motion.time_step_s);
                for (k, (old, new)) in self.lines.iter_mut().zip(&self.fresh).enumerate() {
                    let tau = column.effective_lifetime_s(Line::ALL[k]);
                    let keep = if tau > 0.0 { (-dt / tau).exp() as f32 } else { 0.0 };
                    for (o, n) in old.data_mut().iter_mut().zip(new.data()) {
                        *o = *o * keep + *n * (1.0 - keep);
                    }
                }
            }
            _ => std::mem::swap(&mut self.lines, &mut self.fresh),
        }
        self.glow_started = true;
        self.timings.blur_ms = t.ms();
        let t = clock.stopwatch();
        self.colour();
        if let Some(bg) = &self.background {
            for (out, under) in self.frame.planes_mut().into_iter().zip([&bg.c0, &bg.c1, &bg.c2]) {
                for (o, u) in out.data_mut().iter_mut().zip(under.data()) {
                    *o += *u;
                }
            }
        }
        let time_s = sim.frame() as f64 * f64::from(sim.config().motion.time_step_s);
        if self.settings.stars {
            self.draw_stars(time_s);
        }
        self.draw_night(time_s);
        self.timings.colour_ms = t.ms();
        &self.frame
    }

    /// Emissions of all particles, deposited into the five unblurred line images
    /// `self.fresh`.
    fn emit_and_deposit(&mut self, sim: &AuroraSim) {
        let clock = self.clock.clone();
        let t = clock.stopwatch();
        let particles = sim.particles();
        let n = particles.len().div_ceil(CHUNK);
        let mut chunks = std::mem::take(&mut self.chunks);
        if chunks.len() < n {
            chunks.resize_with(n, BandedPoints::default);
        }
        self.draw_fall_pool(sim);
        let frame = FrameEmission::new(self, sim);
        if let Some(ph) = &frame.lanes
            && self.emit_in_tiles(&frame, ph)
        {
            // Emitted and deposited together; the deposit's time is the tiles' sum.
            self.timings.emit_ms = t.ms() - self.timings.deposit_ms;
            self.chunks = chunks;
            return;
        }
        chunks[..n].par_iter_mut().enumerate().for_each(|(c, points)| {
            points.reset(self.height, self.stride as f32);
            for i in self.strided(c * CHUNK..((c + 1) * CHUNK).min(particles.len())) {
                self.emit_particle(&frame, i, points);
            }
        });
        self.timings.emit_ms = t.ms();
        self.timings.points = chunks[..n].iter().map(BandedPoints::len).sum();
        let t = clock.stopwatch();
        deposit_banded(&chunks[..n], &mut self.fresh);
        self.chunks = chunks;
        self.timings.deposit_ms = t.ms();
    }

    /// The particles of `range` in the subset [`SkyRenderer::set_particle_subset`] keeps
    /// (every `stride`-th from `phase`), in order.
    fn strided(&self, range: std::ops::Range<usize>) -> std::iter::StepBy<std::ops::Range<usize>> {
        let first = range.start + (self.phase + self.stride - range.start % self.stride) % self.stride;
        (first..range.end).step_by(self.stride)
    }

    /// Draw the pool of [`Falls::Pooled`] unless it is drawn for `sim`'s seed and this
    /// salt.
    fn draw_fall_pool(&mut self, sim: &AuroraSim) {
        let params = &self.settings.paper;
        if let Model::Paper { air, emission, pool } = &mut self.model
            && params.falls == Falls::Pooled
        {
            let key = Stream::new(sim.seed(), FALL_POOL_KEY, self.salt).next_u64();
            if pool.as_ref().is_none_or(|p| p.key() != key) {
                let (down, _) = self.settings.field();
                let top = f64::from(self.settings.top_altitude_km);
                *pool = Some(FallPool::new(key, top, down, params, air, emission));
            }
        }
    }

    /// Append particle `i`'s emissions (physical mode: where the frame's small-scale
    /// motion draws it, as bright as it says).
    fn emit_particle(&self, frame: &FrameEmission<'_>, i: usize, out: &mut BandedPoints) {
        let particles = frame.sim.particles();
        let (drawn, gain) = frame.drawn(i);
        if gain <= 0.0 {
            return;
        }
        let foot = frame.foot(drawn);
        let down = frame.down;
        match &self.model {
            Model::Paper { pool: Some(pool), emission, .. } if self.settings.paper.falls == Falls::Pooled => {
                let mut rng = Stream::new(frame.key, EMIT, particles.id[i]);
                let weight = emission.weight();
                for &(offset, line) in pool.pick(rng.next_u64()) {
                    self.push_paper_point(foot + offset.as_dvec3(), weight, line, out);
                }
            }
            Model::Paper { air, emission, .. } => {
                // (`draw_fall_pool` draws the pool before any particle is emitted.)
                debug_assert!(self.settings.paper.falls == Falls::Each, "pooled falls without a pool");
                let mut rng = Stream::new(frame.key, EMIT, particles.id[i]);
                let weight = emission.weight();
                let params = &self.settings.paper;
                paper_emissions(foot, down, params, air, emission, &mut rng, |q, line| {
                    self.push_paper_point(q, weight, line.index() as u8, out);
                });
            }
            Model::Physical { .. } => {
                let Some(column) = self.physical_column(frame, i, foot, gain) else { return };
                if let Some(ph) = &frame.lanes {
                    // The altitudes first, in the scalar path's order; then
                    // the projection in lanes ([`project_in_lanes`]): the same points.
                    let mut lanes = std::mem::take(&mut out.lanes);
                    column.altitudes(&mut lanes);
                    project_in_lanes(ph, column.foot, column.top_km, column.drift, &lanes, |g| {
                        g.splats().for_each(|s| out.push(s));
                    });
                    out.lanes = lanes;
                } else {
                    self.emit_column(&column, out);
                }
            }
        }
    }

    /// Particle `i`'s emission column in the physical model (`None` in paper mode),
    /// standing on `foot` (km, [`FrameEmission::foot`]) with the small-scale motion's
    /// brightness factor `gain`.
    fn physical_column(
        &self,
        frame: &FrameEmission<'_>,
        i: usize,
        foot: DVec3,
        gain: f32,
    ) -> Option<ParticleColumn<'_>> {
        let Model::Physical { sampler, points, photons, .. } = &self.model else { return None };
        // Footprint of one particle at the rest density, km². A point carrying P
        // photons/s seen from d cm through a pixel of solid angle Ω adds a
        // radiance P/(4π d² Ω), i.e. P/(d² Ω 1e6) R. With P = column · area ·
        // 1e10 / points (km² -> cm²) and d in km (d² · 1e10 cm²), that is
        // column · area / (points · 1e6) / (d_km² Ω).
        let area_km2 = f64::from(gain) / frame.rest_density;
        Some(ParticleColumn {
            sampler,
            points,
            photons,
            area_km2,
            xi: frame.offsets.of(i / self.stride),
            foot: foot.as_vec3(),
            top_km: frame.top as f32,
            drift: frame.drift.as_vec3(),
        })
    }

    /// A paper-mode emission at `q` (km) of line index `line`, counting `weight`,
    /// projected with the attenuation to the eye (eq 2.27).
    #[inline]
    fn push_paper_point(&self, q: DVec3, weight: f64, line: u8, out: &mut BandedPoints) {
        if let Some(pr) = self.view.project(q.as_vec3()) {
            let c = attenuation(self.settings.paper.attenuation_per_km, f64::from(pr.depth)) * weight;
            out.push(Splat { x: pr.x_px, y: pr.y_px, weight: c as f32, line });
        }
    }

    /// The physical model's points of `column`, projected one at a time: each adds its
    /// photons times 1/(d² Ω) for the pixel's solid angle Ω.
    fn emit_column(&self, column: &ParticleColumn<'_>, out: &mut BandedPoints) {
        let perspective = self.view.is_perspective();
        let (foot, top, drift) = (column.foot, column.top_km, column.drift);
        for (k, (&m, &column_rate)) in column.points.iter().zip(column.photons).enumerate() {
            if m == 0 {
                continue;
            }
            let per_point = column.per_point(column_rate, m);
            let line = Line::ALL[k];
            let inv_m = 1.0 / m as f32;
            let xi = column.xi[k];
            for j in 0..m {
                let u = (j as f32 + xi) * inv_m;
                let altitude = column.sampler.altitude_km(line, u).min(top);
                let q = Vec3::new(foot.x, altitude, foot.z) + drift * (top - altitude);
                if let Some(pr) = self.view.project(q) {
                    // 1/(d² Ω): for a perspective camera Ω = cos³θ/f², so
                    // 1/(d² Ω) = (f/depth)² · d/depth (one square root).
                    let d2 = (q - self.eye).length_squared();
                    let inverse = if perspective {
                        pr.px_per_m * pr.px_per_m * d2.sqrt() / pr.depth
                    } else {
                        1.0 / (d2 * self.view.pixel_solid_angle(q))
                    };
                    out.push(Splat { x: pr.x_px, y: pr.y_px, weight: per_point * inverse, line: k as u8 });
                }
            }
        }
    }

    /// Luminance, cd/m², that the frame shows as 1.
    fn white_cd_m2(&self) -> f64 {
        let green = self.line_luminance(Line::O557).y;
        match self.settings.mode {
            ColourMode::Paper => {
                // The same emissions land on (1280 / width)² times fewer pixels at a
                // smaller size: scale so the exposure does not depend on the size.
                let pixel_area = (REFERENCE_WIDTH_PX / self.width as f64).powi(2);
                green / f64::from(self.settings.paper_emission_brightness) * pixel_area
            }
            ColourMode::Physical => green * 1e3 * f64::from(self.settings.white_kilorayleigh),
        }
    }

    /// XYZ per unit of a line image: K x̄ȳz̄ (eq 2.29 with K = 683 lm/W) times, in
    /// physical mode, the radiance of 1 R of the line: 1e10/(4π) photons m⁻² s⁻¹ sr⁻¹
    /// times the photon energy hc/λ.
    fn line_luminance(&self, line: Line) -> DVec3 {
        match self.settings.mode {
            ColourMode::Paper => line.table_2_1_cmf() * 683.0,
            ColourMode::Physical => {
                let photon_j = PLANCK_J_S * LIGHT_SPEED_M_PER_S / (line.wavelength_nm() * 1e-9);
                line.cie2015_cmf() * (683.0 * 1e10 / (4.0 * std::f64::consts::PI) * photon_j)
            }
        }
    }

    /// Add the catalogue's stars (at infinity) to the frame, where they stand `time_s`
    /// after the site's moment: a star of magnitude m, dimmed by the extinction, gives
    /// 2.54e-6 · 10^(-0.4 m) lux at the eye, spread over the pixel it falls in
    /// (bilinear), in its blackbody colour.
    fn draw_stars(&mut self, time_s: f64) {
        let limit = self.settings.star_limiting_magnitude;
        let stars = night::catalogue();
        let n = stars.partition_point(|s| s.vmag <= limit);
        if self.star_light.len() != n {
            let white = self.white_cd_m2();
            self.star_light = stars[..n]
                .iter()
                .map(|star| {
                    let xyz = blackbody_xyz(Observer::Cie2015TwoDegree, night::temperature_k(star.bv));
                    let lux = 2.54e-6 * 10f64.powf(-0.4 * f64::from(star.vmag));
                    xyz_to_linear_srgb(xyz / xyz.y * lux / white).max(DVec3::ZERO).as_vec3()
                })
                .collect();
        }
        let site = &self.settings.site;
        let jd = site.julian_day() + time_s / 86_400.0;
        let eye = self.settings.camera.camera().position;
        let [r, g, b] = self.frame.planes_mut();
        for (star, light) in stars[..n].iter().zip(&self.star_light) {
            let dir = night::direction(star, jd, site.latitude_deg, site.longitude_deg);
            let elevation = dir.y.asin();
            if elevation < 0.0 {
                continue;
            }
            let dir = dir.as_vec3();
            let Some(p) = self.view.project(eye + dir * 1e7) else { continue };
            // Luminance = illuminance / the pixel's solid angle.
            let per_pixel =
                night::transmission(elevation) as f32 / self.view.pixel_solid_angle(eye + dir * 1e7);
            for (plane, v) in [&mut *r, &mut *g, &mut *b].into_iter().zip((*light * per_pixel).to_array()) {
                plane.deposit_bilinear(p.x_px, p.y_px, v);
            }
        }
    }

    /// The night behind the aurora and the ground in front of it, in one pass over the
    /// pixels: the airglow (physical mode: each emission's zenith brightness × the van
    /// Rhijn factor of its layer × what extinction leaves, [`night::glow_transmission`],
    /// from a table of 1025 steps in sin(elevation): it changes by at most about 0.3 % a
    /// step), the Milky Way (worked out every [`NIGHT_STEP_PX`] pixels, its map having
    /// 0.5° cells, and interpolated), then the ground: everything below a horizon of low
    /// hills (1-3°, a sum of sines of the azimuth) is black. Each pixel's direction is
    /// interpolated from the grid of ray directions every [`NIGHT_STEP_PX`] pixels
    /// (bilinear between unit vectors 4 px apart: under 10⁻⁴ of a degree off). The
    /// airglow and the ground do not change with time and are worked out at the first
    /// frame only ([`SkyRenderer::still_night`]; the same values as every frame's pass).
    fn draw_night(&mut self, time_s: f64) {
        let airglow = self.settings.airglow && self.settings.mode == ColourMode::Physical;
        let (milky_way, ground) = (self.settings.milky_way, self.settings.ground);
        if !(airglow || milky_way || ground) {
            return;
        }
        if (airglow || ground) && self.still_night.is_empty() {
            self.still_night = self.still_night(airglow, ground);
        }
        let (mw, mw_rgb) = if milky_way { self.milky_way_now(time_s) } else { (Vec::new(), Vec3::ZERO) };
        let grid = &self.night_dirs;
        let w = self.width;
        let still = &self.still_night;
        let [r, g, b] = self.frame.planes_mut();
        r.data_mut()
            .par_chunks_mut(w)
            .zip(g.data_mut().par_chunks_mut(w))
            .zip(b.data_mut().par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, ((r, g), b))| {
                // (Empty with the Milky Way alone: nothing still to add.)
                let still = still.get(y * w..(y + 1) * w);
                for x in 0..w {
                    let Some(mut add) = still.map_or(Some(Vec3::ZERO), |row| row[x]) else {
                        (r[x], g[x], b[x]) = (0.0, 0.0, 0.0);
                        continue;
                    };
                    if milky_way {
                        add += mw_rgb * NightGrid::lerp(&mw, grid.w, grid.at(x, y));
                    }
                    r[x] += add.x;
                    g[x] += add.y;
                    b[x] += add.z;
                }
            });
    }

    /// The night's part that does not change with time, per pixel (row-major): `None`
    /// where the ground hides the sky, else the airglow's linear sRGB (zero without it).
    /// The view and the settings are fixed, so [`SkyRenderer::draw_night`] works it out
    /// once.
    fn still_night(&self, airglow: bool, ground: bool) -> Vec<Option<Vec3>> {
        let glow = if airglow { self.airglow_table() } else { Vec::new() };
        let grid = &self.night_dirs;
        let w = self.width;
        (0..w * self.height)
            .into_par_iter()
            .map(|k| {
                let d = NightGrid::lerp(&grid.dirs, grid.w, grid.at(k % w, k / w));
                let up = d.y / d.length();
                if ground && up < HILLS_TOP_SIN && up.asin() < hills_rad(d.x.atan2(d.z)) {
                    return None;
                }
                let mut add = Vec3::ZERO;
                if airglow && up >= 0.0 {
                    let at = up.min(1.0) * AIRGLOW_STEPS as f32;
                    let j = (at as usize).min(AIRGLOW_STEPS - 1);
                    add += glow[j].lerp(glow[j + 1], at - j as f32);
                }
                Some(add)
            })
            .collect()
    }

    /// The airglow's linear sRGB at sin(elevation) = k / [`AIRGLOW_STEPS`].
    fn airglow_table(&self) -> Vec<Vec3> {
        let white = self.white_cd_m2();
        let layers: Vec<(DVec3, f64)> = self
            .settings
            .airglow_zenith
            .layers()
            .iter()
            .map(|&(nm, rayleigh, height)| {
                let photon_j = PLANCK_J_S * LIGHT_SPEED_M_PER_S / (nm * 1e-9);
                let per_r = spectral_line_xyz(Observer::Cie2015TwoDegree, nm, 1.0)
                    * (683.0 * 1e10 / (4.0 * std::f64::consts::PI) * photon_j);
                (xyz_to_linear_srgb(per_r * rayleigh / white), height)
            })
            .collect();
        let sun = blackbody_xyz(Observer::Cie2015TwoDegree, 5800.0);
        let continuum = xyz_to_linear_srgb(
            sun / sun.y * night::continuum_cd_m2(self.settings.airglow_zenith.continuum_mag_arcsec2) / white,
        );
        (0..=AIRGLOW_STEPS)
            .map(|k| {
                let elevation = (k as f64 / AIRGLOW_STEPS as f64).asin();
                let through = night::glow_transmission(elevation);
                let lines: DVec3 = layers.iter().map(|&(rgb, h)| rgb * night::van_rhijn(elevation, h)).sum();
                ((lines + continuum) * through).max(DVec3::ZERO).as_vec3()
            })
            .collect()
    }

    /// The Milky Way `time_s` after the site's moment: its relative brightness at each
    /// grid point (1 in its brightest level, 0.625 magnitudes fainter a level, a
    /// fractional level below 1 fading in, dimmed like the airglow) and the linear sRGB
    /// of 1 (a 4500 K starlight colour).
    fn milky_way_now(&self, time_s: f64) -> (Vec<f32>, Vec3) {
        let site = &self.settings.site;
        let jd = site.julian_day() + time_s / 86_400.0;
        let star_light = blackbody_xyz(Observer::Cie2015TwoDegree, 4500.0);
        let brightest = night::continuum_cd_m2(self.settings.milky_way_mag_arcsec2) / self.white_cd_m2();
        let rgb = xyz_to_linear_srgb(star_light / star_light.y * brightest).max(DVec3::ZERO).as_vec3();
        let (lat, lon) = (site.latitude_deg, site.longitude_deg);
        let values = self
            .night_dirs
            .dirs
            .par_iter()
            .map(|d| {
                let elevation = night::elevation(*d);
                if !(elevation > -0.05) {
                    return 0.0;
                }
                let (ra, dec) = night::equatorial(d.as_dvec3(), jd, lat, lon);
                let level = night::milky_way_level(ra, dec);
                if level <= 0.0 {
                    return 0.0;
                }
                let relative = 10f32.powf(-0.4 * 0.625 * (5.0 - level.max(1.0))) * level.min(1.0);
                relative * night::glow_transmission(elevation.max(0.0)) as f32
            })
            .collect();
        (values, rgb)
    }

    /// Line images -> XYZ -> linear sRGB into `self.frame`.
    fn colour(&mut self) {
        let paper = self.settings.mode == ColourMode::Paper;
        // XYZ per unit of each line image, divided by the luminance that is to be 1: that
        // of one emission of 557.7 nm (paper) or of `white_kilorayleigh` (physical).
        let white = self.white_cd_m2();
        // Linear sRGB per unit of each line image (the XYZ -> RGB matrix is linear, so it
        // is applied to the five weights once instead of to every pixel).
        let weights: [Vec3; 5] = Line::ALL.map(|line| {
            let xyz = self.line_luminance(line) / white;
            (if paper { xyz_to_rgb_eq_2_30(xyz) } else { xyz_to_linear_srgb(xyz) }).as_vec3()
        });
        let w = self.width;
        let lines = &self.lines;
        let [c0, c1, c2] = self.frame.planes_mut();
        c0.data_mut()
            .par_chunks_mut(w)
            .zip(c1.data_mut().par_chunks_mut(w))
            .zip(c2.data_mut().par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, ((r, g), b))| {
                let rows: [&[f32]; 5] = std::array::from_fn(|k| &lines[k].data()[y * w..(y + 1) * w]);
                for x in 0..w {
                    let mut rgb = Vec3::ZERO;
                    for (row, wk) in rows.iter().zip(&weights) {
                        rgb += *wk * row[x];
                    }
                    r[x] = rgb.x;
                    g[x] = rgb.y;
                    b[x] = rgb.z;
                }
            });
    }
}

/// One particle's emission column in the physical model: `points[k]` points for line k,
/// spread over the altitudes by `sampler`, sharing the column's photon rate
/// `photons[k]` over the particle's footprint `area_km2`; the column stands on `foot`
/// (km, at `top_km`) and leans along the field by `drift` per km of descent.
struct ParticleColumn<'a> {
    sampler: &'a AltitudeSampler,
    points: &'a [u32; 5],
    photons: &'a [f64; 5],
    area_km2: f64,
    /// Each line's offset ξ ∈ [0, 1) of its systematic sample ([`ColumnOffsets`]).
    xi: [f32; 5],
    foot: Vec3,
    top_km: f32,
    drift: Vec3,
}

impl ParticleColumn<'_> {
    /// What each of `m` points of a line of column rate `column_rate` carries (see
    /// [`SkyRenderer::emit_particle`]).
    #[inline]
    fn per_point(&self, column_rate: f64, m: u32) -> f32 {
        (column_rate * self.area_km2 * 1e-6 / f64::from(m)) as f32
    }

    /// The points' (altitude km, per-point weight, line) into `lanes`, in the scalar
    /// path's order: line by line, point j at u = (j + ξ)/m.
    fn altitudes(&self, lanes: &mut Vec<(f32, f32, u8)>) {
        lanes.clear();
        for (k, (&m, &column_rate)) in self.points.iter().zip(self.photons).enumerate() {
            if m == 0 {
                continue;
            }
            let per_point = self.per_point(column_rate, m);
            let inv_m = 1.0 / m as f32;
            let xi = self.xi[k];
            for j in 0..m {
                let u = (j as f32 + xi) * inv_m;
                let altitude = self.sampler.altitude_km(Line::ALL[k], u).min(self.top_km);
                lanes.push((altitude, per_point, k as u8));
            }
        }
    }
}

/// What every particle's emission in one frame shares, worked out once a frame.
struct FrameEmission<'a> {
    sim: &'a AuroraSim,
    /// The small-scale motion now (physical mode, if on).
    small: Option<Prepared>,
    /// The frame's key for the random streams ([`frame_key`]).
    key: u64,
    offsets: ColumnOffsets,
    /// The plane's centre, km: it stands under the scene's origin.
    centre: glam::Vec2,
    /// Altitude of the particles' feet, km.
    top: f64,
    /// [`SkySettings::field`].
    down: DVec3,
    drift: DVec3,
    /// The particles' rest density, km⁻² (at least 1e-12).
    rest_density: f64,
    /// A perspective camera's pinhole when points are projected in lanes.
    lanes: Option<Pinhole>,
}

impl<'a> FrameEmission<'a> {
    fn new(sky: &SkyRenderer, sim: &'a AuroraSim) -> Self {
        let grid = sim.grid();
        let key = frame_key(sim, sky.salt);
        let (down, drift) = sky.settings.field();
        Self {
            sim,
            small: match sky.model {
                Model::Physical { .. } => small_scale_now(sim),
                Model::Paper { .. } => None,
            },
            key,
            offsets: ColumnOffsets::new(key),
            centre: grid.origin_km + grid.extent_km() * 0.5,
            top: f64::from(sky.settings.top_altitude_km),
            down,
            drift,
            rest_density: f64::from(sim.field().rest_density.max(1e-12)),
            lanes: sky.view.pinhole().filter(|ph| ph.perspective && sky.lanes),
        }
    }
}

impl FrameEmission<'_> {
    /// Where particle `i` is drawn (plane km) and its brightness factor: the frame's
    /// small-scale motion applied, if on.
    #[inline]
    fn drawn(&self, i: usize) -> (glam::Vec2, f32) {
        let at = self.sim.particles().position_km[i];
        self.small.as_ref().map_or((at, 1.0), |s| s.apply(at))
    }

    /// The foot (km, at the top altitude) of the column of a particle drawn at `drawn`.
    #[inline]
    fn foot(&self, drawn: glam::Vec2) -> DVec3 {
        let p = drawn - self.centre;
        DVec3::new(f64::from(p.x), self.top, f64::from(p.y))
    }
}

/// The key of `sim`'s current frame for the renderer's random streams (`salt`: see
/// [`SkyRenderer::set_sample_salt`]; 0 leaves the key as it always was).
fn frame_key(sim: &AuroraSim, salt: u64) -> u64 {
    let key = sim.seed() ^ sim.frame().wrapping_mul(0x9e37_79b9_7f4a_7c15);
    if salt == 0 { key } else { Stream::new(key, SALT, salt).next_u64() }
}

/// The offsets ξ of the physical model's systematic samples: particle `i`'s for line k is
/// frac(r_k + (i / stride) φ), φ = (√5 − 1)/2, with one uniform r_k per frame and line
/// (the stride of [`SkyRenderer::set_particle_subset`]: consecutive members of a
/// thinned subset are consecutive in the sequence; stepping it by a stride k instead
/// would step the offsets by frac(k φ), as little as 0.034 for k = 13). Each ξ is
/// uniform, so every particle's points have the distribution of independent offsets
/// (the image's expectation is the same), but particles next to each other in the
/// store (which keeps them in cell order: neighbours in the sky) take offsets spread
/// evenly over [0, 1) (a Weyl sequence: by the three-gap theorem, any run of n
/// consecutive indices cuts the circle into gaps of at most three lengths, here none
/// wider than 2/n), so the columns that land on the same pixels sample their profile
/// together as one column with their points combined: less noise for the same points
/// (test `sampling_quality`).
struct ColumnOffsets {
    base: [f64; 5],
}

impl ColumnOffsets {
    const PHI: f64 = 0.618_033_988_749_894_9;

    fn new(frame_key: u64) -> Self {
        let mut rng = Stream::new(frame_key, EMIT_OFFSETS, 0);
        Self { base: std::array::from_fn(|_| rng.next_f64()) }
    }

    #[inline]
    fn of(&self, i: usize) -> [f32; 5] {
        let step = (i as f64 * Self::PHI).fract();
        // In [0, 1) in f64; as f32 it may round up to 1, which `altitude_km` clamps.
        self.base.map(|r| (r + step).fract() as f32)
    }
}

/// Share `total` emission points among the lines in proportion to the colour each
/// contributes (photon rate × photon energy × (x̄ + ȳ + z̄)), at least 1 for any line
/// that emits at all, so faint lines are sampled but bright ones get the points. (At
/// least 2 until 2026-12-06: the faint lines' second point bought less than a third
/// point of 557.7 nm; test `sampling_quality` measured both.)
fn allocate_points(total: u32, photons: &[f64; 5]) -> [u32; 5] {
    let importance: Vec<f64> = Line::ALL
        .iter()
        .zip(photons)
        .map(|(line, &p)| p / line.wavelength_nm() * line.cie2015_cmf().element_sum())
        .collect();
    let sum: f64 = importance.iter().sum();
    std::array::from_fn(|k| {
        if !(importance[k] > 0.0) || !(sum > 0.0) {
            0
        } else {
            ((f64::from(total) * importance[k] / sum).round() as u32).max(1)
        }
    })
}

/// Eight points from [`project_in_lanes`]: pixel coordinates, weights and lines, lane l a
/// point (one in front of the camera) iff bit l of `ok` is set.
struct Projected8 {
    x: f32x8,
    y: f32x8,
    weight: f32x8,
    lines: [u8; 8],
    ok: u32,
}

impl Projected8 {
    /// The points, in lane order.
    fn splats(&self) -> impl Iterator<Item = Splat> + '_ {
        let (x, y, weight) = (self.x.to_array(), self.y.to_array(), self.weight.to_array());
        (0..8).filter(|l| self.ok & (1 << l) != 0).map(move |l| Splat {
            x: x[l],
            y: y[l],
            weight: weight[l],
            line: self.lines[l],
        })
    }
}

/// The physical mode's points of one particle (`lanes`: altitude km, photons per
/// point, line), projected eight at a time by a perspective camera and given to `emit`
/// eight by eight in their order ([`Projected8`]: those in front of the camera): the
/// point at altitude a is q = (foot.x, a, foot.z) + drift (top - a), and its weight is
/// the photons times 1/(d² Ω) = (f/depth)² · |q - eye|/depth. Every lane takes the
/// scalar path's operations in its order ([`CameraView::project`] as [`Pinhole`]
/// documents it), so the points have the same bits (test `lanes_emit_the_scalar_points`).
fn project_in_lanes(
    ph: &Pinhole,
    foot: Vec3,
    top: f32,
    drift: Vec3,
    lanes: &[(f32, f32, u8)],
    mut emit: impl FnMut(&Projected8),
) {
    const LANES: usize = 8;
    let n = lanes.len();
    let splat = f32x8::splat;
    let (top8, near) = (splat(top), splat(NEAR_M));
    let (fx, fz) = (splat(foot.x), splat(foot.z));
    let (gx, gy, gz) = (splat(drift.x), splat(drift.y), splat(drift.z));
    let (ex, ey, ez) = (splat(ph.eye.x), splat(ph.eye.y), splat(ph.eye.z));
    let dot = |v: Vec3, x: f32x8, y: f32x8, z: f32x8| x * splat(v.x) + y * splat(v.y) + z * splat(v.z);
    let (cx, cy, scale) = (splat(ph.centre_px.0), splat(ph.centre_px.1), splat(ph.scale));
    for at in (0..n).step_by(LANES) {
        let group = &lanes[at..(at + LANES).min(n)];
        let (mut a, mut per_point, mut lines) = ([top; LANES], [0.0; LANES], [0; LANES]);
        for (l, p) in group.iter().enumerate() {
            (a[l], per_point[l], lines[l]) = *p;
        }
        let a = f32x8::from(a);
        let t = top8 - a;
        let (qx, qy, qz) = (fx + gx * t, a + gy * t, fz + gz * t);
        let (dx, dy, dz) = (qx - ex, qy - ey, qz - ez);
        let depth = dot(ph.forward, dx, dy, dz);
        let s = scale / depth;
        let inverse = s * s * (dx * dx + dy * dy + dz * dz).sqrt() / depth;
        emit(&Projected8 {
            x: cx + dot(ph.right, dx, dy, dz) * s,
            y: cy - dot(ph.up, dx, dy, dz) * s,
            weight: f32x8::from(per_point) * inverse,
            lines,
            ok: depth.simd_gt(near).to_bitmask() & ((1 << group.len()) - 1),
        });
    }
}

/// ⌊v⌋ for |v| < 2³¹ (an inlined floor: the library call is not, on baseline x86-64).
#[inline]
fn floor_i32(v: f32) -> i32 {
    let i = v as i32;
    i - i32::from(i as f32 > v)
}

/// Deposit every chunk's banded points into five line images (cleared first). Bands of
/// rows run in parallel, each taking the chunks in order; a splat's second row may be the
/// next band's first, which goes to the band's spill row and is added after all bands,
/// in band order. So every pixel sums the same terms in the same order for any thread
/// count.
fn deposit_banded(chunks: &[BandedPoints], planes: &mut [Plane; 5]) {
    let (w, h) = (planes[0].width(), planes[0].height());
    let spills: Vec<Vec<f32>> = par_chunks5(planes, w * BAND_ROWS)
        .enumerate()
        .map(|(band, mut dst)| {
            let r_lo = band * BAND_ROWS;
            let rows = dst[0].len() / w;
            let mut spill = vec![0.0f32; 5 * w];
            for plane in dst.iter_mut() {
                plane.fill(0.0);
            }
            for points in chunks {
                for s in points.band(band) {
                    deposit(&mut dst, &mut spill, w, r_lo, rows, s);
                }
            }
            spill
        })
        .collect();
    for (band, spill) in spills.iter().enumerate() {
        let row = (band + 1) * BAND_ROWS;
        if row >= h {
            continue;
        }
        for (k, plane) in planes.iter_mut().enumerate() {
            for (d, s) in plane.data_mut()[row * w..(row + 1) * w].iter_mut().zip(&spill[k * w..(k + 1) * w])
            {
                *d += s;
            }
        }
    }
}

/// Where a splat's bilinear footprint starts (the pixel ⌊x − ½⌋, ⌊y − ½⌋) and its four
/// terms, the weight times each pixel's share, in the order (0, 0), (1, 0), (0, 1),
/// (1, 1) of (dx, dy): the one arithmetic every deposit uses, so all give the same bits.
#[inline]
fn bilinear(s: &Splat) -> (i32, i32, [f32; 4]) {
    let (fx, fy) = (s.x - 0.5, s.y - 0.5);
    let (x0, y0) = (floor_i32(fx), floor_i32(fy));
    let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
    let (wx0, wy0) = (1.0 - tx, 1.0 - ty);
    (x0, y0, [s.weight * wx0 * wy0, s.weight * tx * wy0, s.weight * wx0 * ty, s.weight * tx * ty])
}

/// Bilinear deposit of `s` into a band's rows `r_lo..r_lo + rows` of the five line
/// images (`dst`, row-major, width `w`), the row after the band going to `spill`.
#[inline]
fn deposit(dst: &mut [&mut [f32]; 5], spill: &mut [f32], w: usize, r_lo: usize, rows: usize, s: &Splat) {
    let (x0, y0, terms) = bilinear(s);
    let k = usize::from(s.line);
    let (ly, x) = (i64::from(y0) - r_lo as i64, i64::from(x0));
    if ly >= 0 && ly + 1 < rows as i64 && x >= 0 && x + 1 < w as i64 {
        // Both rows in the band and both columns in the image (nearly every point).
        let at = ly as usize * w + x as usize;
        let plane = &mut dst[k][at..at + w + 2];
        plane[0] += terms[0];
        plane[1] += terms[1];
        plane[w] += terms[2];
        plane[w + 1] += terms[3];
        return;
    }
    for (c, term) in terms.into_iter().enumerate() {
        let (dx, dy) = ((c & 1) as i64, (c >> 1) as i64);
        let y = ly + dy;
        let row: &mut [f32] = if (0..rows as i64).contains(&y) {
            &mut dst[k][y as usize * w..(y as usize + 1) * w]
        } else if y == rows as i64 {
            &mut spill[k * w..(k + 1) * w]
        } else {
            continue;
        };
        let x = x + dx;
        if x >= 0 && (x as usize) < w {
            row[x as usize] += term;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use phenomena_core::image::gaussian_weights;

    #[test]
    fn every_camera_kind_has_defaults() {
        // `kind = "dome"` alone was refused ("missing field `fov_deg`").
        let parse = |text: &str| toml::from_str::<SkyCamera>(text).map_err(|e| e.to_string());
        assert_eq!(parse(r#"kind = "dome""#), Ok(SkyCamera::Dome { fov_deg: 180.0 }));
        assert_eq!(parse(r#"kind = "panorama""#), Ok(SkyCamera::Panorama));
        assert_eq!(parse(r#"kind = "ground""#), Ok(SkyCamera::default()));
        assert_eq!(
            parse("kind = \"ground\"\nelevation_deg = 70.0"),
            Ok(SkyCamera::Ground { distance_km: 250.0, elevation_deg: 70.0, fov_y_deg: 60.0 })
        );
        assert_eq!(
            parse(r#"kind = "orbit""#),
            Ok(SkyCamera::Orbit {
                altitude_km: 400.0,
                distance_km: 1000.0,
                look_at_altitude_km: 110.0,
                fov_y_deg: 60.0
            })
        );
        // Every default camera sees the aurora's layer: the plane's centre at 110 km is
        // inside the image.
        for camera in [
            SkyCamera::default(),
            SkyCamera::Dome { fov_deg: 180.0 },
            SkyCamera::Panorama,
            parse(r#"kind = "orbit""#).unwrap(),
        ] {
            let view = camera.camera().view(320, 180).unwrap();
            let p = view.project(Vec3::new(0.0, 110.0, 0.0));
            assert!(
                p.is_some_and(|p| (0.0..320.0).contains(&p.x_px) && (0.0..180.0).contains(&p.y_px)),
                "{camera:?}"
            );
        }
        // A custom camera has no sensible default: it must be given, and the error says so.
        assert!(parse(r#"kind = "custom""#).unwrap_err().contains("camera"));
        // Unknown fields are still refused.
        assert!(parse("kind = \"dome\"\nfov = 180.0").unwrap_err().contains("unknown field"));
    }

    #[test]
    fn deposit_then_blur_is_the_sum_of_splats() {
        // Eq 2.28 per splat (the discrete, normalised Gaussian of the core's blur) at
        // pixel-centre positions, against depositing and blurring once: the same sum, up
        // to f32 rounding. Off-centre positions differ only by the bilinear split.
        let (w, h, sigma) = (48usize, 40usize, 1.7f32);
        let mut rng = Stream::new(5, EMIT, 0);
        let splats: Vec<Splat> = (0..300)
            .map(|_| Splat {
                x: 8.5 + rng.below(32) as f32,
                y: 8.5 + rng.below(24) as f32,
                weight: rng.uniform(0.1, 2.0),
                line: 2,
            })
            .collect();
        let [_, _, mut plane, _, _] = deposit_fresh(&[filed_of(&splats, h)], w, h);
        plane.gaussian_blur(sigma);
        let g = gaussian_weights(sigma);
        let r = (g.len() / 2) as i64;
        let mut direct = vec![0.0f64; w * h];
        for s in &splats {
            let (cx, cy) = ((s.x - 0.5) as i64, (s.y - 0.5) as i64);
            for dy in -r..=r {
                for dx in -r..=r {
                    let (x, y) = (cx + dx, cy + dy);
                    if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                        direct[y as usize * w + x as usize] += f64::from(s.weight)
                            * f64::from(g[(dx + r) as usize])
                            * f64::from(g[(dy + r) as usize]);
                    }
                }
            }
        }
        let max = direct.iter().cloned().fold(0.0, f64::max);
        for (a, b) in plane.data().iter().zip(&direct) {
            // f32 accumulation of up to ~300 terms of size ≤ max: relative 1e-5 of max.
            assert!((f64::from(*a) - b).abs() <= 1e-5 * max, "{a} vs {b}");
        }
        // And the total is conserved: every splat is more than the 4σ kernel radius (7 px)
        // from the edges.
        let total: f64 = splats.iter().map(|s| f64::from(s.weight)).sum();
        assert!((plane.sum() - total).abs() < 1e-4 * total);
    }

    fn filed_of(splats: &[Splat], h: usize) -> BandedPoints {
        let mut points = BandedPoints::default();
        points.reset(h, 1.0);
        for &s in splats {
            points.push(s);
        }
        points
    }

    fn deposit_fresh(chunks: &[BandedPoints], w: usize, h: usize) -> [Plane; 5] {
        let mut planes = std::array::from_fn(|_| Plane::new(w, h));
        deposit_banded(chunks, &mut planes);
        planes
    }

    #[test]
    fn banding_keeps_every_splat_that_touches_the_image() {
        // Splats straddling band borders and image edges: banded deposit equals a plain
        // deposit over the whole image.
        let (w, h) = (20usize, 19usize);
        let mut rng = Stream::new(6, EMIT, 0);
        let splats: Vec<Splat> = (0..500)
            .map(|_| Splat {
                x: rng.uniform(-1.0, 21.0),
                y: rng.uniform(-1.0, 20.0),
                weight: 1.0,
                line: rng.below(5) as u8,
            })
            .collect();
        // Two chunks, as the renderer makes them.
        let chunks = [filed_of(&splats[..200], h), filed_of(&splats[200..], h)];
        let banded = deposit_fresh(&chunks, w, h);
        // Images reused from an earlier frame are cleared first.
        let mut reused: [Plane; 5] = std::array::from_fn(|_| Plane::new(w, h));
        for p in &mut reused {
            p.data_mut().fill(7.0);
        }
        deposit_banded(&chunks, &mut reused);
        assert_eq!(reused, banded);
        let mut whole: [Vec<f32>; 5] = std::array::from_fn(|_| vec![0.0f32; w * h]);
        let mut spill = vec![0.0f32; 5 * w];
        for s in &splats {
            let [a, b, c, d, e] = &mut whole;
            deposit(&mut [a, b, c, d, e], &mut spill, w, 0, h, s);
        }
        for k in 0..5 {
            for (a, b) in banded[k].data().iter().zip(&whole[k]) {
                assert!((a - b).abs() < 1e-5, "line {k}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn the_perspective_shortcut_is_the_solid_angle_formula() {
        let view = Camera {
            position: Vec3::new(0.0, 0.002, -250.0),
            look_at: Vec3::new(0.0, 60.0, 0.0),
            up: Vec3::Y,
            projection: Projection::Perspective { fov_y_deg: 60.0 },
        }
        .view(1280, 720)
        .unwrap();
        for q in [Vec3::new(0.0, 110.0, 0.0), Vec3::new(-180.0, 250.0, 90.0), Vec3::new(150.0, 95.0, -120.0)]
        {
            let pr = view.project(q).unwrap();
            let d2 = (q - Vec3::new(0.0, 0.002, -250.0)).length_squared();
            let shortcut = pr.px_per_m * pr.px_per_m * d2.sqrt() / pr.depth;
            let general = 1.0 / (d2 * view.pixel_solid_angle(q));
            assert!((shortcut / general - 1.0).abs() < 1e-5, "{q}: {shortcut} vs {general}");
        }
    }

    #[test]
    fn lanes_emit_the_scalar_points() {
        // Physical mode, perspective cameras looking up and across the curtain: every
        // particle's points from the lanes equal the scalar path's, bit for bit, in order.
        let mut config = crate::AuroraConfig::default();
        config.motion.particles = 3_000;
        config.redistribution.enabled = false;
        let mut sim = AuroraSim::new(config, 3).unwrap();
        sim.step().unwrap();
        for camera in [
            SkyCamera::default(),
            SkyCamera::Orbit {
                altitude_km: 200.0,
                distance_km: 900.0,
                look_at_altitude_km: 150.0,
                fov_y_deg: 30.0,
            },
        ] {
            let settings = SkySettings { camera, ..SkySettings::default() };
            let mut sky = SkyRenderer::new(settings, 320, 180, None).unwrap();
            let mut emitted = [BandedPoints::default(), BandedPoints::default()];
            assert!(small_scale_now(&sim).is_some(), "the small-scale motion is on by default");
            for (lanes, points) in [true, false].into_iter().zip(&mut emitted) {
                sky.lanes = lanes;
                points.reset(180, 1.0);
                let frame = FrameEmission::new(&sky, &sim);
                for i in 0..sim.particles().len() {
                    sky.emit_particle(&frame, i, points);
                }
            }
            assert!(emitted[0].len() > 10_000, "{} points", emitted[0].len());
            assert_eq!(emitted[0].bands, emitted[1].bands);
        }
    }

    #[test]
    fn neighbours_offsets_leave_no_gap_wider_than_two_over_n() {
        // Runs of n consecutive particles, anywhere in the store: their offsets for one
        // line, sorted round the circle, leave no gap over 2/n (the golden ratio's
        // largest gap times n is at most 1.89 for n < 600, whatever the start).
        let offsets = ColumnOffsets::new(12345);
        for n in [2usize, 3, 10, 50, 233, 599] {
            for start in [0usize, 1, 977, 123_456, 399_000] {
                for k in 0..5 {
                    let mut xi: Vec<f32> = (start..start + n).map(|i| offsets.of(i)[k]).collect();
                    assert!(xi.iter().all(|x| (0.0..=1.0).contains(x)), "{xi:?}");
                    xi.sort_by(f32::total_cmp);
                    let wrap = 1.0 - xi[n - 1] + xi[0];
                    let widest = xi.windows(2).map(|w| w[1] - w[0]).fold(wrap, f32::max);
                    assert!(widest * n as f32 <= 2.0, "n {n}, start {start}: widest gap {widest}");
                }
            }
        }
        // Another frame shifts every line's offsets by its own uniform draw.
        let other = ColumnOffsets::new(54321);
        assert_ne!(offsets.of(7), other.of(7));
        assert_ne!(offsets.of(7)[0], offsets.of(7)[1]);
    }

    #[test]
    fn points_go_where_the_colour_is() {
        let p = allocate_points(40, &[1.0, 0.3, 5.0, 0.5, 0.0]);
        assert_eq!(p[4], 0, "a dark line gets no points");
        assert!(p[2] > p[0] && p[2] > p[3], "{p:?}");
        assert!(
            p.iter().enumerate().all(|(k, &n)| k == 4 || n >= 1),
            "every emitting line gets a point: {p:?}"
        );
        let faint = allocate_points(5, &[1.0, 1e-6, 5.0, 1e-6, 0.0]);
        assert_eq!((faint[1], faint[3], faint[4]), (1, 1, 0), "a faint line still gets a point: {faint:?}");
    }
}
