//! Simulation parameters of the flame, deserialisable from a scene's `[flame]` table.
//!
//! The paper (Inagaki et al.) prints its equations but no parameter table: it reports
//! about 3,000 particles at 60 fps (§6.2, Figs 8-10) and says that mass and temperature
//! are constants given at the burner (§4.3). The defaults below are ours, chosen so that
//! the paper's scene has about 3,000 particles, a flame about 0.8 m tall, and a stable
//! explicit step at 60 fps; each field says its unit.

use crate::air::AirParams;
use glam::Vec3;
use phenomena_core::grid::MAX_CELLS;
use phenomena_core::kernel::KernelKind;
use phenomena_core::validate::{Issue, Issues};
use serde::{Deserialize, Serialize};

/// Which method the simulation follows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// The paper as printed: each particle keeps the temperature it was born with (§4.1),
    /// pressure may be negative (eq 11), and the only external force is the wind (§4.2.3).
    /// The `[flame.extended]` table is ignored. Rendering is chosen separately in
    /// `[render]`: the paper's Fig 1 colours are `brightness = "normalized"` and its
    /// per-pixel splats `resolution_scale = 1` (as in `scenes/flame-paper.toml`).
    Paper,
    /// The paper plus documented extensions from `[flame.extended]`: temperature cools with
    /// age (Newton's law) so the tips redden, hot gas is buoyant, and negative pressure
    /// can be clamped to zero (no tensile clumping of a freely expanding gas).
    #[default]
    Extended,
}

/// Complete flame simulation configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FlameConfig {
    /// Paper or extended method.
    pub mode: Mode,
    /// Duration of one frame, seconds (the paper runs at 60 fps).
    pub frame_time_s: f32,
    /// SPH substeps per frame (the paper does one step per frame, §4.3).
    pub substeps: u32,
    /// SPH parameters (§4.2).
    pub sph: SphParams,
    /// Where and how particles are added (§4.3 step 1).
    pub emitter: Emitter,
    /// The external force (§4.2.3).
    pub wind: Wind,
    /// Extension parameters, used only in `extended` mode.
    pub extended: Extended,
    /// Particles leaving this box are removed.
    pub domain: Domain,
    /// Upper bound on live particles; emission pauses at the cap (counted in the stats).
    pub max_particles: u32,
}

impl Default for FlameConfig {
    fn default() -> Self {
        Self {
            mode: Mode::Extended,
            frame_time_s: 1.0 / 60.0,
            substeps: 1,
            sph: SphParams::default(),
            emitter: Emitter::default(),
            wind: Wind::default(),
            extended: Extended::default(),
            domain: Domain::default(),
            max_particles: 200_000,
        }
    }
}

/// Smoothed-particle hydrodynamics parameters (paper §4.2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SphParams {
    /// Kernel support radius d of eq (2), metres.
    pub support_radius_m: f32,
    /// Mass m of every particle, kg (constant, §4.1).
    pub particle_mass_kg: f32,
    /// Reference density ρ0 of eq (11), kg/m³.
    pub rest_density_kg_m3: f32,
    /// Gas constant k of eq (11), m²/s² (p = k(ρ - ρ0); √k is the speed of sound).
    pub gas_constant_m2_s2: f32,
    /// Kernel whose gradient drives the pressure force of eq (12): `poly6` as printed,
    /// or `spiky`, whose gradient does not vanish at r = 0.
    pub pressure_kernel: KernelKind,
}

impl Default for SphParams {
    fn default() -> Self {
        Self {
            support_radius_m: 0.04,
            particle_mass_kg: 1.0e-5,
            rest_density_kg_m3: 1.0,
            gas_constant_m2_s2: 0.1,
            pressure_kernel: KernelKind::Spiky,
        }
    }
}

/// The burner: a horizontal disk that adds particles every frame (§4.3 step 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Emitter {
    /// Centre of the burner disk, metres.
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub position_m: Vec3,
    /// Radius of the burner disk (in the x-z plane), metres.
    pub radius_m: f32,
    /// Particles added per second (spread evenly over frames, fractions carried over).
    pub rate_per_s: f32,
    /// Initial velocity, m/s.
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub velocity_m_s: Vec3,
    /// Standard deviation of a random velocity added per axis, m/s.
    pub velocity_jitter_m_s: f32,
    /// Temperature at birth, kelvin.
    pub temperature_k: f32,
    /// Mean lifetime, seconds (the paper is silent on removal; see the crate docs).
    pub lifetime_s: f32,
    /// Lifetimes are uniform in `lifetime_s × [1 - j, 1 + j]` for this fraction j.
    pub lifetime_jitter: f32,
}

impl Default for Emitter {
    fn default() -> Self {
        Self {
            position_m: Vec3::ZERO,
            radius_m: 0.08,
            rate_per_s: 3000.0,
            velocity_m_s: Vec3::new(0.0, 0.8, 0.0),
            velocity_jitter_m_s: 0.05,
            temperature_k: 1900.0,
            lifetime_s: 1.0,
            lifetime_jitter: 0.3,
        }
    }
}

/// The wind: a force per unit volume added to every particle (paper §4.2.3 and §6, where
/// it is the mouse-drag vector), constant or keyframed.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Wind {
    /// Constant wind force density, N/m³ (used when `keys` is empty).
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub force_n_m3: Vec3,
    /// Keyframes, linearly interpolated in time and held constant outside their span.
    pub keys: Vec<WindKey>,
}

/// One wind keyframe.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindKey {
    /// Time of the key, seconds from the start.
    pub time_s: f32,
    /// Wind force density at that time, N/m³.
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub force_n_m3: Vec3,
}

impl Wind {
    /// The wind force density at `time_s`.
    pub fn force_at(&self, time_s: f32) -> Vec3 {
        let keys = &self.keys;
        match keys.len() {
            0 => self.force_n_m3,
            _ if time_s <= keys[0].time_s => keys[0].force_n_m3,
            _ => {
                for pair in keys.windows(2) {
                    let (a, b) = (&pair[0], &pair[1]);
                    if time_s <= b.time_s {
                        let span = b.time_s - a.time_s;
                        let t = if span > 0.0 { (time_s - a.time_s) / span } else { 1.0 };
                        return a.force_n_m3.lerp(b.force_n_m3, t);
                    }
                }
                keys[keys.len() - 1].force_n_m3
            }
        }
    }
}

/// Extensions beyond the paper (used only in `extended` mode).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Extended {
    /// Ambient air temperature, kelvin.
    pub ambient_temperature_k: f32,
    /// Newtonian cooling time constant: T = T_amb + (T_0 - T_amb)·exp(-age/τ), seconds.
    pub cooling_time_s: f32,
    /// Standard deviation of the birth temperature, kelvin.
    pub temperature_jitter_k: f32,
    /// Upward buoyant acceleration per kelvin above ambient, m/s²/K.
    pub buoyancy_m_s2_per_k: f32,
    /// Treat negative pressure as zero (a gas does not pull on itself).
    pub clamp_negative_pressure: bool,
    /// The air around the flame ([`crate::air`]): when enabled, the air is buoyant and
    /// carries the particles, and `buoyancy_m_s2_per_k` no longer acts on them directly.
    pub air: AirParams,
}

impl Default for Extended {
    fn default() -> Self {
        Self {
            ambient_temperature_k: 300.0,
            cooling_time_s: 1.5,
            temperature_jitter_k: 80.0,
            buoyancy_m_s2_per_k: 1.0e-3,
            clamp_negative_pressure: true,
            air: AirParams::default(),
        }
    }
}

/// The simulation box; particles outside it are removed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Domain {
    /// Lower corner, metres.
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub min_m: Vec3,
    /// Upper corner, metres.
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub max_m: Vec3,
}

impl Default for Domain {
    fn default() -> Self {
        Self { min_m: Vec3::new(-2.0, -0.5, -2.0), max_m: Vec3::new(2.0, 3.0, 2.0) }
    }
}

/// Most particles one frame may emit.
pub const MAX_EMITTED_PER_FRAME: f64 = 100_000.0;

/// Whether the burner disk lies inside the domain box.
fn burner_inside(e: &Emitter, d: &Domain) -> bool {
    let r = Vec3::new(e.radius_m, 0.0, e.radius_m);
    (e.position_m - r).cmpge(d.min_m).all() && (e.position_m + r).cmple(d.max_m).all()
}

impl FlameConfig {
    /// The largest emission rate the SPH step can take at this burner, per second, or
    /// `None` when it cannot be predicted (a point burner or gas born at rest).
    ///
    /// Gas leaves a burner disk of radius r at speed v, so at steady state the number
    /// density just above it is n = rate / (π r² v) (continuity); a particle there has
    /// about n · (4/3) π d³ neighbours within the support radius d. The step refuses more
    /// than [`crate::MAX_NEIGHBORS`], so the rate must stay below
    /// MAX_NEIGHBORS · π r² v / ((4/3) π d³). Buoyancy and jitter only spread the gas,
    /// so the bound errs towards accepting what then runs (tested at 0.9 of it).
    pub fn max_burner_rate_per_s(&self) -> Option<f64> {
        let e = &self.emitter;
        let (r, v, d) =
            (f64::from(e.radius_m), f64::from(e.velocity_m_s.length()), f64::from(self.sph.support_radius_m));
        let ball = 4.0 / 3.0 * std::f64::consts::PI * d.powi(3);
        let disk_flow = std::f64::consts::PI * r * r * v;
        (disk_flow > 0.0 && ball > 0.0).then(|| crate::sim::MAX_NEIGHBORS as f64 * disk_flow / ball)
    }

    /// Every problem with this configuration, each naming the field (relative to the
    /// `[flame]` table), the value and the valid range.
    pub fn validate(&self) -> Result<(), Vec<Issue>> {
        let mut i = Issues::default();
        i.range_open_low("frame_time_s", self.frame_time_s, 0.0, 1.0);
        i.count("substeps", u64::from(self.substeps), 1..=64);
        i.count("max_particles", u64::from(self.max_particles), 1..=2_000_000);

        let s = &self.sph;
        i.range("sph.support_radius_m", s.support_radius_m, 1e-4..=100.0);
        i.range_open_low("sph.particle_mass_kg", s.particle_mass_kg, 0.0, 1e6);
        i.range_open_low("sph.rest_density_kg_m3", s.rest_density_kg_m3, 0.0, 1e6);
        i.range("sph.gas_constant_m2_s2", s.gas_constant_m2_s2, 0.0..=1e6);
        if s.pressure_kernel == KernelKind::CubicSpline {
            i.push("sph.pressure_kernel", "\"cubic-spline\"", "\"poly6\" or \"spiky\"");
        }

        self.validate_emitter(&mut i);
        self.validate_wind(&mut i);

        let x = &self.extended;
        i.range("extended.ambient_temperature_k", x.ambient_temperature_k, 0.0..=40_000.0);
        i.range_open_low("extended.cooling_time_s", x.cooling_time_s, 0.0, 1e6);
        i.range("extended.temperature_jitter_k", x.temperature_jitter_k, 0.0..=10_000.0);
        i.range("extended.buoyancy_m_s2_per_k", x.buoyancy_m_s2_per_k, -1.0..=1.0);
        x.air.validate("extended.air.", &mut i);
        if self.mode == Mode::Extended && x.air.enabled && !(self.emitter.radius_m > 0.0) {
            i.push("emitter.radius_m", self.emitter.radius_m, "a burner of positive radius: the air's grid is sized by its diameter (or set extended.air.enabled = false)");
        }
        x.air.validate_obstacles("extended.air.", self.emitter.radius_m.max(0.0), &mut i);
        let air_on = self.mode == Mode::Extended && x.air.enabled;
        if !x.air.obstacles.is_empty() && !air_on {
            i.push(
                "extended.air.obstacles",
                format!("{} obstacles", x.air.obstacles.len()),
                "obstacles stand in the air around the flame: set extended.air.enabled = true, with mode = \"extended\"",
            );
        }
        // The air's buoyancy is g·(T - T_a)/T: it needs an ambient above absolute zero.
        if self.mode == Mode::Extended && x.air.enabled && !(x.ambient_temperature_k >= 1.0) {
            i.push(
                "extended.ambient_temperature_k",
                x.ambient_temperature_k,
                "at least 1 K with the air on (extended.air.enabled)",
            );
        }

        self.validate_domain(&mut i);
        i.into_result()
    }

    /// The `[emitter]` table's problems, into `i`: its fields, and its rate against the
    /// particles one frame may add and against the burner's crowding limit.
    fn validate_emitter(&self, i: &mut Issues) {
        let e = &self.emitter;
        i.vector("emitter.position_m", &e.position_m.to_array(), 1e6);
        i.range("emitter.radius_m", e.radius_m, 0.0..=100.0);
        i.range("emitter.rate_per_s", e.rate_per_s, 0.0..=1e7);
        i.vector("emitter.velocity_m_s", &e.velocity_m_s.to_array(), 1e3);
        i.range("emitter.velocity_jitter_m_s", e.velocity_jitter_m_s, 0.0..=1e3);
        i.range("emitter.temperature_k", e.temperature_k, 1.0..=40_000.0);
        i.range_open_low("emitter.lifetime_s", e.lifetime_s, 0.0, 1e4);
        i.range("emitter.lifetime_jitter", e.lifetime_jitter, 0.0..=1.0);
        // One frame's particles land on the burner at once: bound them so a typo cannot
        // pile millions of particles onto one disk.
        let per_frame = f64::from(e.rate_per_s) * f64::from(self.frame_time_s);
        if per_frame.is_finite() && per_frame > MAX_EMITTED_PER_FRAME {
            i.push(
                "emitter.rate_per_s",
                e.rate_per_s,
                format!(
                    "at most {MAX_EMITTED_PER_FRAME} particles per frame (rate × frame_time_s is {per_frame:.0})"
                ),
            );
        }

        if let Some(limit) = self.max_burner_rate_per_s()
            && f64::from(e.rate_per_s) > limit
        {
            i.push(
                "emitter.rate_per_s",
                e.rate_per_s,
                format!(
                    "at most about {limit:.0} for this burner: faster, each new particle near the burner would have more than {} neighbours within sph.support_radius_m (widen emitter.radius_m, raise emitter.velocity_m_s or lower the rate)",
                    crate::sim::MAX_NEIGHBORS
                ),
            );
        }
    }

    /// The `[wind]` table's problems, into `i`: a constant force or keys in time order.
    fn validate_wind(&self, i: &mut Issues) {
        i.vector("wind.force_n_m3", &self.wind.force_n_m3.to_array(), 1e6);
        for (k, key) in self.wind.keys.iter().enumerate() {
            i.range(&format!("wind.keys[{k}].time_s"), key.time_s, 0.0..=1e7);
            i.vector(&format!("wind.keys[{k}].force_n_m3"), &key.force_n_m3.to_array(), 1e6);
            if k > 0 && !(key.time_s >= self.wind.keys[k - 1].time_s) {
                i.push(
                    format!("wind.keys[{k}].time_s"),
                    key.time_s,
                    format!("a time not before the previous key ({} s)", self.wind.keys[k - 1].time_s),
                );
            }
        }
        if !self.wind.keys.is_empty() && self.wind.force_n_m3 != Vec3::ZERO {
            i.push(
                "wind.force_n_m3",
                format!("{:?}", self.wind.force_n_m3.to_array()),
                "either a constant force or keys, not both",
            );
        }
    }

    /// The `[domain]` table's problems, into `i`: a box with the burner inside, of at most
    /// [`MAX_CELLS`] grid cells of size `sph.support_radius_m`.
    fn validate_domain(&self, i: &mut Issues) {
        let (d, e, s) = (&self.domain, &self.emitter, &self.sph);
        i.vector("domain.min_m", &d.min_m.to_array(), 1e6);
        i.vector("domain.max_m", &d.max_m.to_array(), 1e6);
        if !d.max_m.cmpgt(d.min_m).all() {
            i.push("domain.max_m", format!("{:?}", d.max_m.to_array()), "every component above domain.min_m");
        } else if !burner_inside(e, d) {
            i.push(
                "emitter.position_m",
                format!("{:?}", e.position_m.to_array()),
                format!(
                    "a burner (radius {} m) inside the domain {:?}..{:?}",
                    e.radius_m,
                    d.min_m.to_array(),
                    d.max_m.to_array()
                ),
            );
        } else if s.support_radius_m > 0.0 {
            let cells = ((d.max_m - d.min_m) / s.support_radius_m).ceil() + Vec3::ONE;
            let cells = f64::from(cells.x) * f64::from(cells.y) * f64::from(cells.z);
            if cells > MAX_CELLS as f64 {
                i.push(
                    "domain.max_m",
                    format!("{:?}", d.max_m.to_array()),
                    format!(
                        "a box of at most {MAX_CELLS} cells of size sph.support_radius_m (this one has {cells:.0})"
                    ),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        assert_eq!(FlameConfig::default().validate(), Ok(()));
    }

    #[test]
    fn every_problem_is_reported_with_its_field() {
        let mut c = FlameConfig::default();
        c.sph.gas_constant_m2_s2 = -1.0;
        c.emitter.temperature_k = 0.0;
        c.wind.keys = vec![
            WindKey { time_s: 2.0, force_n_m3: Vec3::X },
            WindKey { time_s: 1.0, force_n_m3: Vec3::NAN },
        ];
        c.domain.max_m = Vec3::new(1.0, -3.0, 1.0);
        let errs = c.validate().unwrap_err();
        let fields: Vec<&str> = errs.iter().map(|e| e.field.as_str()).collect();
        assert_eq!(
            fields,
            [
                "sph.gas_constant_m2_s2",
                "emitter.temperature_k",
                "wind.keys[1].force_n_m3",
                "wind.keys[1].time_s",
                "domain.max_m"
            ]
        );
        assert_eq!(errs[0].to_string(), "sph.gas_constant_m2_s2 = -1: expected a value in [0, 1000000]");
    }

    #[test]
    fn wind_keys_interpolate_and_hold() {
        let w = Wind {
            force_n_m3: Vec3::ZERO,
            keys: vec![
                WindKey { time_s: 1.0, force_n_m3: Vec3::new(-2.0, 0.0, 0.0) },
                WindKey { time_s: 3.0, force_n_m3: Vec3::new(2.0, 0.0, 0.0) },
            ],
        };
        assert_eq!(w.force_at(0.0).x, -2.0);
        assert_eq!(w.force_at(2.0).x, 0.0);
        assert_eq!(w.force_at(9.0).x, 2.0);
    }
}
