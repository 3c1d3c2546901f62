//! Aurora parameters, deserialisable from a scene's `[aurora]` table. Defaults follow
//! the thesis's Tables 3.2 and 3.3 where it gives values; the rest are ours, documented.

use crate::noise::{FractalNoise, NoiseKind};
use glam::Vec2;
use phenomena_core::validate::{Issue, Issues};
use serde::{Deserialize, Serialize};

use crate::field::{Poisson, Sampler};
use crate::shape::{Keyframe, Merge, Resample, Split};
use crate::small_scale::SmallScale;

/// Most keyframes.
pub(crate) const MAX_KEYFRAMES: u64 = 256;
/// Most control points of one keyframe, all sheets together (e.g. 64 sheets of 32).
pub(crate) const MAX_CONTROL_POINTS: u64 = 2048;
/// Most splits, and most merges.
pub(crate) const MAX_OPERATIONS: u64 = 1024;
/// Most mouse samples of one stroke.
pub(crate) const MAX_STROKE_SAMPLES: u64 = 100_000;

/// Largest keyframe frame: shapes are interpolated in `f32`, which counts whole frames
/// exactly up to 2²⁴ (about 6.5 days at 30 frames per second).
pub(crate) const MAX_KEYFRAME: u64 = 1 << 24;

/// Complete aurora configuration (part 1: shapes, field, motion, redistribution).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AuroraConfig {
    /// The simulation plane (x-z, seen from above).
    pub plane: Plane,
    /// How strokes become shapes over time.
    pub shape: ShapeParams,
    /// The source shape (first) and target shapes (later), with their frames.
    pub keyframes: Vec<Keyframe>,
    /// Splits (Fig 2.4).
    pub splits: Vec<Split>,
    /// Merges (Fig 2.5).
    pub merges: Vec<Merge>,
    /// The electric field (§2.2.3).
    pub field: FieldParams,

    /// Charged-particle motion (§2.3).
    pub motion: MotionParams,
    /// Removing and adding particles when the shape is renewed (§2.3.4, Table 3.3).
    pub redistribution: Redistribution,
    /// Folds, curls, rays, thinning ends, flicker and pulsation drawn on top of the
    /// simulated particles (an extension: [`crate::small_scale`]).
    pub small_scale: SmallScale,
}

impl Default for AuroraConfig {
    fn default() -> Self {
        Self {
            plane: Plane::default(),
            shape: ShapeParams::default(),
            keyframes: default_keyframes(),
            splits: Vec::new(),
            merges: Vec::new(),
            field: FieldParams::default(),
            motion: MotionParams::default(),
            redistribution: Redistribution::default(),
            small_scale: SmallScale::default(),
        }
    }
}

/// A gentle single-sheet arc that sways: something to see with no keyframes given.
fn default_keyframes() -> Vec<Keyframe> {
    let arc = |bend: f32| -> Vec<[f32; 2]> {
        (0..9)
            .map(|i| {
                let t = i as f32 / 8.0;
                [60.0 + 280.0 * t, 200.0 + bend * (std::f32::consts::PI * t).sin()]
            })
            .collect()
    };
    vec![Keyframe { frame: 0, sheets: vec![arc(-40.0)] }, Keyframe { frame: 140, sheets: vec![arc(50.0)] }]
}

/// The x-z simulation plane and its grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Plane {
    /// Size of the plane (x, z), km; shapes are drawn in [0, size].
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec2")]
    pub size_km: Vec2,
    /// Grid cells along x and z (Table 3.2: 256 × 256).
    pub cells: [u32; 2],
}

impl Default for Plane {
    fn default() -> Self {
        Self { size_km: Vec2::splat(400.0), cells: [256, 256] }
    }
}

/// Shapes and their renewal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShapeParams {
    /// Control points per sheet, n (Fig 3.1: 32).
    pub control_points_per_sheet: u32,
    /// Resampling rule of eq (2.1).
    pub resample: Resample,
    /// The intermediate target shape is regenerated every K frames (§2.2.2: 5-10).
    pub renew_every_frames: u32,
    /// The renewed shape is the one this many frames ahead: where the particles should
    /// be when the next renewal comes (0 = the current frame's shape).
    pub lookahead_frames: u32,
}

impl Default for ShapeParams {
    fn default() -> Self {
        Self {
            control_points_per_sheet: 32,
            resample: Resample::Endpoints,
            renew_every_frames: 7,
            lookahead_frames: 7,
        }
    }
}

/// The electric field of the intermediate target shape.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FieldParams {
    /// Charges are placed within this distance L_thr of the shape's segments, km.
    pub reach_km: f32,
    /// Charges placed per renewal (their counts per cell are N(i, j)).
    pub charges: u32,
    /// How charges are placed.
    pub sampler: Sampler,
    /// How the Poisson equation is solved.
    pub poisson: Poisson,
    /// Noise added to the potential (Fig 2.11): `amplitude` is relative to the largest
    /// |φ|, `frequency` in cycles per km; time advances at `time_frequency_hz`.
    pub noise: FractalNoise,
    /// Rate at which the noise's third coordinate advances, per second.
    pub noise_time_frequency_hz: f64,
}

impl Default for FieldParams {
    fn default() -> Self {
        Self {
            reach_km: 6.0,
            charges: 120_000,
            sampler: Sampler::Direct,
            poisson: Poisson::Direct,
            noise: FractalNoise {
                kind: NoiseKind::Perlin,
                seed: 0,
                octaves: 3,
                frequency: 1.0 / 40.0,
                amplitude: 0.15,
                lacunarity: 2.0,
                persistence: 0.5,
            },
            noise_time_frequency_hz: 0.5,
        }
    }
}

/// Which SPH kernels make the pseudo-Coulomb force (§2.3.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CoulombKernels {
    /// Poly6 density (eq 2.11-2.12) and spiky gradient (eq 2.15-2.16): stronger close
    /// repulsion, a more diffuse aurora.
    Poly6Spiky,
    /// The cubic spline for both (eq 2.17-2.18): sharper rays; the thesis's choice for
    /// its experiments (§3.2).
    #[default]
    Spline,
}

/// 0.003 electron masses: see [`MotionParams::particle_mass_kg`].
const EFFECTIVE_MASS_KG: f64 = 0.003 * 9.109_383_701_5e-31;

/// Charged-particle motion (§2.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MotionParams {
    /// Particles placed near the source shape at the start (Table 3.2: 120,000).
    pub particles: u32,
    /// Time step Δt, seconds (Table 3.2: 0.0333), which is also the frame time: one
    /// frame is one step, so a scene plays in real time at 1/Δt frames per second, and
    /// the flicker's hertz and the pulsation's seconds ([`crate::small_scale`]) are real
    /// ones. Also read as `frame_time_s`.
    #[serde(alias = "frame_time_s")]
    pub time_step_s: f32,
    /// Kernel pair of the pseudo-Coulomb force.
    pub kernels: CoulombKernels,
    /// SPH support radius, km (for the spline, twice its smoothing length h). The
    /// thesis gives none; 0.35 km gives the 120,000 particles about twenty neighbours.
    pub support_km: f32,
    /// Gas constant k of eq (2.13), km⁴/s² (scales the repulsion per unit of density
    /// excess). The thesis gives none. 3 keeps every cell of thesis scenes 1-5 under
    /// Table 3.3's upper threshold of 500 after each redistribution (at 2, up to 14
    /// cells of scene 1 stay above it, the per-cell removal cap of 100 not enough); the
    /// scenario tests check it.
    pub gas_constant: f32,
    /// Weight w_L of the Lorentz force in eq (2.19)-(2.20).
    pub weight_lorentz: f32,
    /// Weight w_P of the pseudo-Coulomb force.
    pub weight_coulomb: f32,
    /// Charge q0, coulombs (the elementary charge, as in §2.2.3).
    pub charge_c: f64,
    /// Vacuum permittivity ε0, F/m.
    pub permittivity_f_m: f64,
    /// Effective mass of a simulated charged particle, kg. The thesis gives none; with
    /// its charge q0 and 120,000 charges per renewal, 2.7e-33 kg (0.003 electron masses)
    /// lets particles follow shapes that move about 20 km/s (100 km per 140-frame
    /// transition).
    pub particle_mass_kg: f64,
    /// Magnetic field along y, tesla. Earth's ~5e-5 T would spin the particles 10⁹ times
    /// a second; the default gives a gyration of 0.5 rad/s, a slow swirl (E × B drift)
    /// on top of the fall towards the shape.
    pub magnetic_field_t: f64,
    /// Speed limit, km/s: §2.3.3 normalises velocities "for energy conservation" without
    /// saying how; we cap each particle's speed, so kinetic energy stays bounded (no
    /// particle exceeds ½ m v²_max).
    pub max_speed_km_s: f32,
    /// Velocity damping rate γ, 1/s (v is scaled by exp(-γΔt) each step). Without it a
    /// particle that falls into the shape's potential well oscillates across it forever
    /// and spends most of its time at the turning points, doubling the sheet. Part of
    /// our reading of §2.3.3's "velocity normalisation for energy conservation".
    /// Stronger damping holds particles closer to the shape at the cost of a slower
    /// response. The default, 6/s (a velocity memory of 5 frames), is the smallest whole
    /// rate that keeps 90 % of the particles within L_thr over the last 40 frames of
    /// every thesis scene. Why particles leave: the potential of the
    /// whole shape is a bowl, and beyond L_thr its pull towards the shape's centre of
    /// charge outweighs the sheet's own well in places (a third of the cells 1-1.5 L_thr
    /// from scene 5's four sheets have E pointing away from the nearest sheet); the
    /// particles there drift out at a speed ~ force/γ, between renewals, with or without
    /// the pseudo-Coulomb pressure. Worst share over the last 40 frames of scenes 1-5
    /// with redistribution rule `"reach"`: 0.89/0.95/0.89/0.88/0.76 at 2/s,
    /// 0.96/0.99/0.97/0.95/0.90 at 5/s, 0.97/0.995/0.97/0.96/0.92 at 6/s,
    /// 0.98/0.999/0.98/0.97/0.94 at 8/s. The price: the particles that stay fill the
    /// near cells towards Table 3.3's 50 each (scene 5 ends with 415,000 particles at
    /// 6/s, 245,000 at 2/s).
    pub damping_per_s: f32,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            particles: 120_000,
            time_step_s: 0.0333,
            kernels: CoulombKernels::Spline,
            support_km: 0.35,
            gas_constant: 3.0,
            weight_lorentz: 0.6,
            weight_coulomb: 0.4,
            charge_c: 1.602_176_634e-19,
            permittivity_f_m: 8.854_187_812_8e-12,
            particle_mass_kg: EFFECTIVE_MASS_KG,
            magnetic_field_t: 0.5 * EFFECTIVE_MASS_KG / 1.602_176_634e-19,
            max_speed_km_s: 40.0,
            damping_per_s: 6.0,
        }
    }
}

/// Which rules redistribution (§2.3.4) follows at each renewal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RedistributionRule {
    /// §2.3.4 as printed: particles in cells that are not near the old shape are removed,
    /// near cells over `remove_above` lose at most `remove_max` of their farthest
    /// particles, near cells under `add_below` gain at most `add_max` particles anywhere
    /// in the cell.
    Paper,
    /// The printed rules with three changes that keep the promise of Table 3.3's
    /// thresholds:
    /// - a near cell over `remove_above` loses its whole excess (farthest first), so no
    ///   cell holds more than `remove_above` right after a renewal; `remove_max` does not
    ///   apply (with it, at the default damping, scenes 1 and 2 leave 1 and 6 cells over
    ///   500 after a renewal);
    /// - particles farther than L_thr from the old shape are removed too, not only those
    ///   in cells that are not near: a cell is near when a charge within L_thr lands in
    ///   it, so near cells reach up to a cell diagonal past L_thr, and what lies there has
    ///   been pulled off the sheet (the field of the whole shape draws particles towards
    ///   its centre of charge: the mean radial velocity beyond L_thr is outwards);
    /// - particles are added only within L_thr (positions drawn in the cell until one is
    ///   within L_thr, at most 16 draws each), and a cell only partly within L_thr is
    ///   topped up to that part of `add_below`, so the edge of the sheet is not denser
    ///   than its middle.
    ///
    /// Worst share of particles within L_thr over the last 40 frames of thesis scenes 1-5
    /// at the default damping: 0.955/0.987/0.970/0.937/0.877 with `"paper"`,
    /// 0.970/0.995/0.978/0.964/0.928 with `"reach"` (`examples/redistribution_report.rs`).
    #[default]
    Reach,
}

/// Redistribution thresholds (Table 3.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Redistribution {
    /// Whether to redistribute at all (Fig 2.14 compares both).
    pub enabled: bool,
    /// Which rules: the thesis's as printed (`"paper"`) or with the changes that keep
    /// its thresholds' promise (`"reach"`, the default); see [`RedistributionRule`].
    pub rule: RedistributionRule,
    /// A cell is near the shape if its charge count is at least this × the mean count.
    pub near_count_ratio: f32,
    /// ... and its potential at most this × the mean potential (potentials are negative
    /// near the shape).
    pub near_potential_ratio: f32,
    /// Near cells with fewer particles than this gain particles.
    pub add_below: u32,
    /// At most this many particles are added per cell per renewal.
    pub add_max: u32,
    /// Near cells with more particles than this lose their farthest from the shape.
    pub remove_above: u32,
    /// At most this many particles are removed per cell per renewal (rule `"paper"`
    /// only: rule `"reach"` removes the whole excess).
    pub remove_max: u32,
}

impl Default for Redistribution {
    fn default() -> Self {
        Self {
            enabled: true,
            rule: RedistributionRule::Reach,
            near_count_ratio: 0.10,
            near_potential_ratio: 0.25,
            add_below: 50,
            add_max: 10,
            remove_above: 500,
            remove_max: 100,
        }
    }
}

impl AuroraConfig {
    /// The shapes as an [`Animation`](crate::shape::Animation): the strokes resampled to
    /// `shape.control_points_per_sheet` points, checked, with the splits and merges.
    pub fn animation(&self) -> Result<crate::shape::Animation, crate::shape::ShapeError> {
        crate::shape::Animation::build(
            &self.keyframes,
            &self.splits,
            &self.merges,
            self.shape.control_points_per_sheet as usize,
            self.shape.resample,
        )
    }

    /// Every problem, each naming the field (relative to `[aurora]`), value and range.
    /// Shape problems (crossings, bad splits) are found when the shapes are built.
    pub fn validate(&self) -> Result<(), Vec<Issue>> {
        let mut i = Issues::default();
        i.vector("plane.size_km", &self.plane.size_km.to_array(), 1e5);
        if !(self.plane.size_km.min_element() > 0.0) {
            i.push("plane.size_km", format!("{:?}", self.plane.size_km.to_array()), "positive sizes");
        }
        for (a, &c) in self.plane.cells.iter().enumerate() {
            i.count(&format!("plane.cells[{a}]"), u64::from(c), 3..=4096);
        }
        i.count("shape.control_points_per_sheet", u64::from(self.shape.control_points_per_sheet), 2..=4096);
        i.count("shape.renew_every_frames", u64::from(self.shape.renew_every_frames), 1..=10_000);
        i.count("shape.lookahead_frames", u64::from(self.shape.lookahead_frames), 0..=10_000);
        self.validate_keyframe_count(&mut i);
        self.validate_source_in_plane(&mut i);
        i.count("splits", self.splits.len() as u64, 0..=MAX_OPERATIONS);
        i.count("merges", self.merges.len() as u64, 0..=MAX_OPERATIONS);
        self.validate_strokes(&mut i);
        self.validate_field(&mut i);
        self.validate_motion(&mut i);
        self.validate_redistribution(&mut i);
        self.small_scale.validate(&mut i, "small_scale");
        i.into_result()
    }

    /// The `keyframes` list's size, into `i`: a source and at least one target, and
    /// bounds that keep building the shapes (a crossing test of every pair of segments
    /// per keyframe) within about a second whatever the file holds.
    fn validate_keyframe_count(&self, i: &mut Issues) {
        if self.keyframes.len() < 2 {
            i.push("keyframes", self.keyframes.len(), "a source and at least one target keyframe");
        }
        i.count("keyframes", self.keyframes.len() as u64, 0..=MAX_KEYFRAMES);
        let n = u64::from(self.shape.control_points_per_sheet);
        if let Some(kf) = self.keyframes.first()
            && n * kf.sheets.len() as u64 > MAX_CONTROL_POINTS
        {
            i.push(
                "keyframes[0].sheets",
                format!("{} sheets of {n} control points", kf.sheets.len()),
                format!("at most {MAX_CONTROL_POINTS} control points per keyframe in all"),
            );
        }
    }

    /// Particles are born on the source keyframe's sheets: with none of its points in the
    /// plane nothing would ever be drawn (into `i`).
    fn validate_source_in_plane(&self, i: &mut Issues) {
        let size = self.plane.size_km;
        let inside = |p: &[f32; 2]| {
            let p = Vec2::from(*p);
            p.cmpge(Vec2::ZERO).all() && p.cmple(size).all()
        };
        if let Some(kf) = self.keyframes.first()
            && !kf.sheets.is_empty()
            && !kf.sheets.iter().flatten().any(inside)
        {
            i.push(
                "keyframes[0].sheets",
                "no point inside the plane",
                format!(
                    "a source shape with points in the plane, x and z in [0, {}] × [0, {}] km (nothing would be drawn)",
                    size.x, size.y
                ),
            );
        }
    }

    /// Every keyframe's frame and strokes, into `i`: frames exact in f32, strokes of at
    /// most [`MAX_STROKE_SAMPLES`] samples, each within the vector bound of 1e5 km.
    fn validate_strokes(&self, i: &mut Issues) {
        for (k, kf) in self.keyframes.iter().enumerate() {
            // Frames are interpolated in f32, exact for whole numbers up to 2²⁴.
            i.count(&format!("keyframes[{k}].frame"), u64::from(kf.frame), 0..=MAX_KEYFRAME);
            for (s, sheet) in kf.sheets.iter().enumerate() {
                if sheet.len() as u64 > MAX_STROKE_SAMPLES {
                    i.push(
                        format!("keyframes[{k}].sheets[{s}]"),
                        format!("{} samples", sheet.len()),
                        format!("at most {MAX_STROKE_SAMPLES} samples per stroke"),
                    );
                }
                for (p, pt) in sheet.iter().enumerate() {
                    i.vector(&format!("keyframes[{k}].sheets[{s}][{p}]"), pt, 1e5);
                }
            }
        }
    }

    /// The `[field]` table's problems, into `i`.
    fn validate_field(&self, i: &mut Issues) {
        let f = &self.field;
        i.range_open_low("field.reach_km", f.reach_km, 0.0, 1e4);
        i.count("field.charges", u64::from(f.charges), 1..=10_000_000);
        if let Poisson::GaussSeidel { max_iterations, tolerance } = f.poisson {
            i.count("field.poisson.max_iterations", u64::from(max_iterations), 1..=10_000_000);
            i.range_open_low("field.poisson.tolerance", tolerance, 0.0, 1.0);
        }
        i.count("field.noise.octaves", u64::from(f.noise.octaves), 0..=12);
        i.range("field.noise.amplitude", f.noise.amplitude, 0.0..=10.0);
        i.range("field.noise.frequency", f.noise.frequency, 0.0..=1e3);
        i.range("field.noise_time_frequency_hz", f.noise_time_frequency_hz, 0.0..=1e3);
    }

    /// The `[motion]` table's problems, into `i`.
    fn validate_motion(&self, i: &mut Issues) {
        let m = &self.motion;
        i.count("motion.particles", u64::from(m.particles), 0..=5_000_000);
        i.range_open_low("motion.time_step_s", m.time_step_s, 0.0, 10.0);
        i.range_open_low("motion.support_km", m.support_km, 0.0, 1e4);
        i.range("motion.gas_constant", m.gas_constant, 0.0..=1e9);
        i.range("motion.weight_lorentz", m.weight_lorentz, 0.0..=1e3);
        i.range("motion.weight_coulomb", m.weight_coulomb, 0.0..=1e3);
        i.range_open_low("motion.charge_c", m.charge_c, 0.0, 1.0);
        i.range_open_low("motion.permittivity_f_m", m.permittivity_f_m, 0.0, 1.0);
        i.range_open_low("motion.particle_mass_kg", m.particle_mass_kg, 0.0, 1.0);
        i.range("motion.magnetic_field_t", m.magnetic_field_t, -1.0..=1.0);
        i.range_open_low("motion.max_speed_km_s", m.max_speed_km_s, 0.0, 1e5);
        i.range("motion.damping_per_s", m.damping_per_s, 0.0..=1e3);
    }

    /// The `[redistribution]` table's problems, into `i`.
    fn validate_redistribution(&self, i: &mut Issues) {
        let r = &self.redistribution;
        i.range("redistribution.near_count_ratio", r.near_count_ratio, 0.0..=1e3);
        i.range("redistribution.near_potential_ratio", r.near_potential_ratio, 0.0..=1e3);
        i.count("redistribution.add_max", u64::from(r.add_max), 0..=1_000_000);
        i.count("redistribution.remove_max", u64::from(r.remove_max), 0..=1_000_000);
        if r.add_below > r.remove_above {
            i.push(
                "redistribution.add_below",
                r.add_below,
                format!("at most redistribution.remove_above ({})", r.remove_above),
            );
        }
    }

    /// The grid of the plane.
    pub fn grid(&self) -> crate::field::Grid {
        let cells = [self.plane.cells[0].max(1) as usize, self.plane.cells[1].max(1) as usize];
        crate::field::Grid {
            nx: cells[0],
            nz: cells[1],
            origin_km: Vec2::ZERO,
            cell_km: (self.plane.size_km.x / cells[0] as f32).max(self.plane.size_km.y / cells[1] as f32),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        assert_eq!(AuroraConfig::default().validate(), Ok(()));
    }

    #[test]
    fn problems_are_named() {
        let mut c = AuroraConfig::default();
        c.motion.time_step_s = f32::NAN;
        c.plane.cells = [2, 256];
        c.keyframes.truncate(1);
        let fields: Vec<String> = c.validate().unwrap_err().into_iter().map(|i| i.field).collect();
        assert_eq!(fields, ["plane.cells[0]", "keyframes", "motion.time_step_s"]);
    }
}
