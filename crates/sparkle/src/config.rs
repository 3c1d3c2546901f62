//! The `[sparkle]` table: the Phong glint model, the light, the camera and the particle
//! population. `Default` is the diamond-dust setting of the paper (§3.1: uniform normals,
//! one-sided facets, a directional sun, no distance falloff), scaled to a volume that
//! holds 10⁹ crystals at a real diamond-dust density.

use glam::Vec3;
use phenomena_core::camera::{Camera, Projection};
use phenomena_core::validate::{Issue, Issues};
use serde::{Deserialize, Serialize};

/// How the visible particles are found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// The paper's stochastic model (§2): only particles whose normal lies in the visible
    /// cone are created; each frame those leaving it are deleted and newcomers are born.
    #[default]
    Stochastic,
    /// The "conventional method" of Table 1: every virtual particle is created, moved and
    /// tested each frame. For the statistical tests and the speed and memory comparison.
    BruteForce,
}

/// The Phong specular term of §2: a facet is seen when k_s I_l (N·H)^n ≥ I_e.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Phong {
    /// Specular reflection coefficient k_s.
    pub specular_k_s: f32,
    /// Light intensity I_l (linear; also scales the glint's brightness).
    pub light_intensity: f32,
    /// Visibility threshold I_e (same units as k_s I_l).
    pub threshold_i_e: f32,
    /// Phong exponent n.
    pub exponent_n: f32,
    /// Facets reflect from both faces (|N·H| instead of N·H). The paper counts one face
    /// (its sin²θ/4); thin ice plates and leaves reflect from both, doubling the count.
    pub two_sided: bool,
}

impl Default for Phong {
    fn default() -> Self {
        // ratio I_e/(k_s I_l) = 0.0025 with n = 10,000 gives cos θ = 0.0025^(1/n):
        // θ = 1.98°, a visible fraction (1 - cos θ)/2 = 3.0e-4 (the issue's benchmark).
        Self {
            specular_k_s: 1.0,
            light_intensity: 1.0,
            threshold_i_e: 0.0025,
            exponent_n: 10_000.0,
            two_sided: false,
        }
    }
}

impl Phong {
    /// cos θ of the visible cone, θ = arccos((I_e/(k_s I_l))^(1/n)) (§2); `None` when
    /// the cone is empty (I_e ≥ k_s I_l: no facet can be seen).
    pub fn cos_theta(&self) -> Option<f64> {
        let ratio =
            f64::from(self.threshold_i_e) / (f64::from(self.specular_k_s) * f64::from(self.light_intensity));
        if !(ratio < 1.0) {
            return None;
        }
        Some(ratio.max(0.0).powf(1.0 / f64::from(self.exponent_n)))
    }

    /// The fraction of uniformly oriented facets that are seen: (1 - cos θ)/2 per face,
    /// exact. The paper's A/W ≈ sin²θ/4 is its small-angle form: since
    /// (1 - cos θ)/2 = sin²(θ/2) and sin²θ/4 = sin²(θ/2) cos²(θ/2), the paper's value is
    /// smaller by the factor cos²(θ/2), about θ²/4 relative (3·10⁻⁴ at θ = 2°, 7 % at 30°).
    pub fn uniform_fraction(&self) -> f64 {
        let Some(c) = self.cos_theta() else { return 0.0 };
        let one_side = 0.5 * (1.0 - c);
        if self.two_sided { 2.0 * one_side } else { one_side }
    }
}

/// The light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Light {
    /// A directional sun. Azimuth 0 is the world's −z (straight ahead of a camera looking
    /// along −z), 90° is +x; elevation is above the horizontal (+y up). Both may move at
    /// a constant rate (leaf glitter's moving sun, Fig 3).
    Sun {
        /// Azimuth at time 0, degrees.
        azimuth_deg: f32,
        /// Elevation at time 0, degrees.
        elevation_deg: f32,
        /// Azimuth rate, degrees per second.
        #[serde(default)]
        azimuth_rate_deg_per_s: f32,
        /// Elevation rate, degrees per second.
        #[serde(default)]
        elevation_rate_deg_per_s: f32,
    },
    /// A point light (a street lamp) at a fixed position, metres.
    Point {
        /// Position, metres.
        #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
        position_m: Vec3,
    },
}

impl Light {
    /// The `[light]` table's problems, into `i`.
    fn validate(&self, i: &mut Issues) {
        match *self {
            Light::Sun { azimuth_deg, elevation_deg, azimuth_rate_deg_per_s, elevation_rate_deg_per_s } => {
                i.range("light.azimuth_deg", azimuth_deg, -3600.0..=3600.0);
                i.range("light.elevation_deg", elevation_deg, -90.0..=90.0);
                i.range("light.azimuth_rate_deg_per_s", azimuth_rate_deg_per_s, -360.0..=360.0);
                i.range("light.elevation_rate_deg_per_s", elevation_rate_deg_per_s, -90.0..=90.0);
            }
            Light::Point { position_m } => i.vector("light.position_m", &position_m.to_array(), 1e7),
        }
    }

    /// Where the light is at time `t_s`.
    pub fn at(&self, t_s: f32) -> LightAt {
        match *self {
            Light::Sun { azimuth_deg, elevation_deg, azimuth_rate_deg_per_s, elevation_rate_deg_per_s } => {
                let az = (azimuth_deg + azimuth_rate_deg_per_s * t_s).to_radians();
                let el = (elevation_deg + elevation_rate_deg_per_s * t_s).to_radians();
                LightAt::Direction(Vec3::new(el.cos() * az.sin(), el.sin(), -el.cos() * az.cos()))
            }
            Light::Point { position_m } => LightAt::Position(position_m),
        }
    }
}

/// The light at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightAt {
    /// Unit direction towards a distant light.
    Direction(Vec3),
    /// Position of a point light, metres.
    Position(Vec3),
}

/// How facet normals are distributed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Normals {
    /// Uniform over the sphere (§3.1).
    Uniform,
    /// Horizontal plates: normals around +y with a tilt spread (a von Mises-Fisher lobe
    /// with κ = 1/σ², σ the tilt in radians). An extension: gives sun pillars and subsuns.
    Plates {
        /// Tilt spread σ, degrees (real plates: 0.5-12°).
        tilt_deg: f32,
    },
}

/// Diamond dust (§3.1): crystals in a box of air.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Dust {
    /// Box corner with the smallest coordinates, metres.
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub box_min_m: Vec3,
    /// Box corner with the largest coordinates, metres.
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub box_max_m: Vec3,
    /// Crystals per cubic metre (real diamond dust: about 10³-10⁴).
    pub density_per_m3: f64,
    /// Settling speed under gravity (terminal velocity), metres per second.
    pub fall_speed_m_per_s: f32,
    /// Steady wind, metres per second.
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub wind_m_per_s: Vec3,
    /// Gust amplitude: a smooth random velocity shared by all crystals, metres per second.
    pub gust_m_per_s: f32,
    /// Each crystal's own random displacement per frame, uniform in a cube of half-side this speed
    /// times the frame time, metres per second.
    pub turbulence_m_per_s: f32,
    /// Largest random rotation of a crystal per frame, degrees (uniform in [0, this]
    /// about a random axis).
    pub rotation_deg_per_frame: f32,
    /// Normal distribution.
    pub normals: Normals,
}

impl Default for Dust {
    fn default() -> Self {
        // 10⁹ crystals at 5,000 per m³ in a 200,000 m³ box around the viewer.
        Self {
            box_min_m: Vec3::new(-50.0, 0.0, -100.0),
            box_max_m: Vec3::new(50.0, 20.0, 0.0),
            density_per_m3: 5_000.0,
            fall_speed_m_per_s: 0.3,
            wind_m_per_s: Vec3::new(0.5, 0.0, 0.0),
            gust_m_per_s: 0.3,
            turbulence_m_per_s: 0.1,
            rotation_deg_per_frame: 0.5,
            normals: Normals::Uniform,
        }
    }
}

/// Leaf glitter (§3.2): leaves on a hemisphere standing for a tree's crown.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Leaves {
    /// Centre of the hemisphere's base, metres (the dome rises along +y).
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub centre_m: Vec3,
    /// Crown radius, metres.
    pub radius_m: f32,
    /// Number of leaves.
    pub count: u64,
    /// Spread of leaf normals around the crown's surface normal, degrees (a von
    /// Mises-Fisher lobe with κ = 1/σ²): most leaves face outwards, fewer tilt away.
    pub spread_deg: f32,
}

impl Default for Leaves {
    fn default() -> Self {
        Self { centre_m: Vec3::new(0.0, 0.0, -12.0), radius_m: 4.0, count: 2_000_000, spread_deg: 25.0 }
    }
}

/// The particle population.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Population {
    /// Diamond dust (§3.1).
    DiamondDust(Dust),
    /// Leaf glitter (§3.2).
    LeafGlitter(Leaves),
}

/// Everything that defines a sparkle simulation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SparkleConfig {
    /// Stochastic (the paper's model) or brute force.
    pub method: Method,
    /// Frames per second (the time step is 1/fps).
    pub fps: f32,
    /// The glint model.
    pub phong: Phong,
    /// The light.
    pub light: Light,
    /// The camera (perspective or orthographic); glints are seen from its position.
    pub camera: Camera,
    /// The particles.
    pub population: Population,
    /// Frames a facet that stopped being seen is still followed (unseen), so that if it
    /// turns back into the cone it reappears where it was, as in the full system. With 0
    /// (the paper's plain "delete") every newcomer is drawn afresh and such quick returns
    /// come back anywhere. More frames cost more held facets (about deaths × frames).
    pub memory_frames: u32,
}

impl Default for SparkleConfig {
    fn default() -> Self {
        Self {
            method: Method::Stochastic,
            fps: 30.0,
            phong: Phong::default(),
            light: Light::Sun {
                azimuth_deg: 20.0,
                elevation_deg: 12.0,
                azimuth_rate_deg_per_s: 0.0,
                elevation_rate_deg_per_s: 0.0,
            },
            camera: Camera {
                position: Vec3::new(0.0, 1.6, 0.0),
                look_at: Vec3::new(0.0, 4.0, -20.0),
                up: Vec3::Y,
                projection: Projection::Perspective { fov_y_deg: 60.0 },
            },
            population: Population::DiamondDust(Dust::default()),
            memory_frames: 4,
        }
    }
}

/// Most virtual particles a scene may hold.
pub const MAX_VIRTUAL: f64 = 1e13;
/// Most particles a brute-force run may create (32 bytes each: 6.4 GB).
pub const MAX_BRUTE_FORCE: u64 = 200_000_000;
/// Most glints a frame may expect (memory guard: 32 bytes each).
pub const MAX_EXPECTED_VISIBLE: f64 = 5e7;
/// Most candidate facets a frame may draw (time guard).
pub const MAX_CANDIDATES: f64 = 2e8;
/// Narrowest visible cone, degrees: below it the f32 visibility test cannot resolve the
/// cone's edge to the margin the samplers leave (1e-4 rad).
pub const MIN_CONE_DEG: f64 = 0.25;

impl SparkleConfig {
    /// Number of virtual particles N (dust: density × box volume, rounded).
    pub fn virtual_count(&self) -> u64 {
        match self.population {
            Population::DiamondDust(d) => {
                let v = (d.box_max_m - d.box_min_m).as_dvec3();
                (d.density_per_m3 * v.x * v.y * v.z).round().clamp(0.0, MAX_VIRTUAL) as u64
            }
            Population::LeafGlitter(l) => l.count,
        }
    }

    /// Frame time, seconds.
    pub fn dt_s(&self) -> f32 {
        1.0 / self.fps
    }

    /// Every problem, with the field, its value and the valid range.
    pub fn validate(&self) -> Result<(), Vec<Issue>> {
        let mut i = Issues::default();
        i.range("fps", self.fps, 0.01..=10_000.0);
        i.count("memory_frames", u64::from(self.memory_frames), 0..=64);
        let p = &self.phong;
        i.range_open_low("phong.specular_k_s", p.specular_k_s, 0.0, 1e6);
        i.range_open_low("phong.light_intensity", p.light_intensity, 0.0, 1e9);
        i.range("phong.threshold_i_e", p.threshold_i_e, 0.0..=1e9);
        i.range_open_low("phong.exponent_n", p.exponent_n, 0.0, 1e8);
        self.light.validate(&mut i);
        self.camera.validate_planar(&mut i, "camera");
        let n = self.virtual_count();
        match self.population {
            Population::DiamondDust(d) => d.validate(&mut i),
            Population::LeafGlitter(l) => l.validate(&mut i),
        }
        if self.method == Method::BruteForce && n > MAX_BRUTE_FORCE {
            i.push(
                "method",
                "\"brute-force\"",
                format!("a population of at most {MAX_BRUTE_FORCE} for brute force (this one has {n}): use the stochastic method"),
            );
        }
        if i.is_empty() {
            self.validate_cone(n, &mut i);
        }
        i.into_result()
    }

    /// The `[phong]` cone (§2: the facets whose N·H reaches the threshold's cos θ) in a
    /// configuration otherwise valid, for a population of `n`: narrower than 90° (with a
    /// frame's rotation) for two-sided facets, at least [`MIN_CONE_DEG`] wide, and giving
    /// at most [`MAX_CANDIDATES`] candidates (stochastic, uniform normals) and
    /// [`MAX_EXPECTED_VISIBLE`] visible particles per frame.
    fn validate_cone(&self, n: u64, i: &mut Issues) {
        let p = &self.phong;
        let margin = self.step_rotation_rad();
        let Some(c) = p.cos_theta() else { return };
        let theta = c.acos();
        if p.two_sided && theta + margin >= std::f64::consts::FRAC_PI_2 - 1e-3 {
            i.push(
                "phong.threshold_i_e",
                p.threshold_i_e,
                format!(
                    "a cone narrower than 90° for two-sided facets (θ = {:.1}° plus the rotation per frame): raise the threshold or the exponent",
                    theta.to_degrees()
                ),
            );
        }
        if theta.to_degrees() < MIN_CONE_DEG {
            i.push(
                "phong.exponent_n",
                p.exponent_n,
                format!(
                    "a visible cone of at least {MIN_CONE_DEG}° (this one is {:.4}°): lower the exponent or the threshold",
                    theta.to_degrees()
                ),
            );
        }
        if self.method == Method::Stochastic {
            let sides = if p.two_sided { 2.0 } else { 1.0 };
            let cap = 0.5 * sides * (1.0 - (theta + margin + 1e-4).min(std::f64::consts::PI).cos());
            let uniform =
                matches!(self.population, Population::DiamondDust(Dust { normals: Normals::Uniform, .. }));
            if uniform && n as f64 * cap > MAX_CANDIDATES {
                i.push(
                    "phong.threshold_i_e",
                    p.threshold_i_e,
                    format!(
                        "fewer than {MAX_CANDIDATES:e} candidate facets per frame: the cone plus a frame's rotation gives {:.3e}; raise the threshold or the exponent, lower the rotation or the count",
                        n as f64 * cap
                    ),
                );
            }
        }
        let expected = n as f64 * self.upper_fraction();
        if expected > MAX_EXPECTED_VISIBLE {
            i.push(
                "phong.threshold_i_e",
                p.threshold_i_e,
                format!(
                    "fewer than {MAX_EXPECTED_VISIBLE:e} visible particles: this cone would show about {expected:.3e}; raise the threshold, the exponent or lower the count"
                ),
            );
        }
    }

    /// Largest rotation of a normal in one frame, radians (0 for static leaves).
    pub fn step_rotation_rad(&self) -> f64 {
        match self.population {
            Population::DiamondDust(d) => f64::from(d.rotation_deg_per_frame).to_radians(),
            Population::LeafGlitter(_) => 0.0,
        }
    }

    /// Facets expected in view, where known in advance (uniform normals: N times the
    /// cone's fraction); `None` for normal lobes, whose share depends on the geometry
    /// frame by frame (the simulation bounds it by its candidate guard).
    pub fn expected_visible(&self) -> Option<f64> {
        let f = self.upper_fraction();
        (f > 0.0).then(|| self.virtual_count() as f64 * f)
    }

    /// The visible fraction where it is known in advance (uniform normals); lobes are
    /// checked by `SparkleSim::new` against their candidate bound for the scene's geometry.
    fn upper_fraction(&self) -> f64 {
        match self.population {
            Population::DiamondDust(Dust { normals: Normals::Uniform, .. }) => self.phong.uniform_fraction(),
            _ => 0.0,
        }
    }
}

impl Dust {
    /// The `[population]` table's problems for diamond dust, into `i`: the box, the
    /// density (with at most [`MAX_VIRTUAL`] crystals in the box) and the motion.
    fn validate(&self, i: &mut Issues) {
        let (d, f) = (self, "population");
        i.vector(&format!("{f}.box_min_m"), &d.box_min_m.to_array(), 1e6);
        i.vector(&format!("{f}.box_max_m"), &d.box_max_m.to_array(), 1e6);
        if d.box_min_m.is_finite() && d.box_max_m.is_finite() && !d.box_min_m.cmplt(d.box_max_m).all() {
            i.push(
                format!("{f}.box_max_m"),
                format!("{:?}", d.box_max_m.to_array()),
                format!("every component above box_min_m {:?}", d.box_min_m.to_array()),
            );
        }
        if !(d.density_per_m3 > 0.0 && d.density_per_m3 <= 1e12) {
            i.push(format!("{f}.density_per_m3"), d.density_per_m3, "a value in (0, 1e12] crystals per m³");
        }
        i.range(&format!("{f}.fall_speed_m_per_s"), d.fall_speed_m_per_s, -100.0..=100.0);
        i.vector(&format!("{f}.wind_m_per_s"), &d.wind_m_per_s.to_array(), 100.0);
        i.range(&format!("{f}.gust_m_per_s"), d.gust_m_per_s, 0.0..=100.0);
        i.range(&format!("{f}.turbulence_m_per_s"), d.turbulence_m_per_s, 0.0..=100.0);
        i.range(&format!("{f}.rotation_deg_per_frame"), d.rotation_deg_per_frame, 0.0..=90.0);
        if let Normals::Plates { tilt_deg } = d.normals {
            i.range_open_low(&format!("{f}.normals.tilt_deg"), tilt_deg, 0.0, 90.0);
        }
        if d.box_min_m.is_finite() && d.box_max_m.is_finite() {
            let v = (d.box_max_m - d.box_min_m).as_dvec3();
            let count = d.density_per_m3 * v.x.max(0.0) * v.y.max(0.0) * v.z.max(0.0);
            if count > MAX_VIRTUAL {
                i.push(
                    format!("{f}.density_per_m3"),
                    d.density_per_m3,
                    format!("at most {MAX_VIRTUAL:e} crystals in the box (this gives {count:.3e})"),
                );
            }
        }
    }
}

impl Leaves {
    /// The `[population]` table's problems for leaf glitter, into `i`.
    fn validate(&self, i: &mut Issues) {
        let (l, f) = (self, "population");
        i.vector(&format!("{f}.centre_m"), &l.centre_m.to_array(), 1e6);
        i.range_open_low(&format!("{f}.radius_m"), l.radius_m, 0.0, 1e5);
        i.count(&format!("{f}.count"), l.count, 1..=MAX_VIRTUAL as u64);
        i.range_open_low(&format!("{f}.spread_deg"), l.spread_deg, 0.0, 180.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_holds_a_billion() {
        let c = SparkleConfig::default();
        c.validate().unwrap();
        assert_eq!(c.virtual_count(), 1_000_000_000);
        // (1 - cos θ)/2 with cos θ = 0.0025^(1e-4): about 3.0e-4.
        let p = c.phong.uniform_fraction();
        assert!((p - 2.995e-4).abs() < 1e-6, "{p}");
    }

    #[test]
    fn empty_cone_is_reported_as_none() {
        let p = Phong { threshold_i_e: 2.0, ..Phong::default() };
        assert_eq!(p.cos_theta(), None);
        assert_eq!(p.uniform_fraction(), 0.0);
    }

    #[test]
    fn bad_values_name_field_and_range() {
        let mut c = SparkleConfig::default();
        c.phong.exponent_n = -1.0;
        if let Population::DiamondDust(d) = &mut c.population {
            d.density_per_m3 = 0.0;
            d.box_max_m.x = -60.0;
        }
        c.fps = f32::NAN;
        let e = c.validate().unwrap_err();
        let fields: Vec<&str> = e.iter().map(|i| i.field.as_str()).collect();
        assert_eq!(fields, ["fps", "phong.exponent_n", "population.box_max_m", "population.density_per_m3"]);
        let c = SparkleConfig { method: Method::BruteForce, ..SparkleConfig::default() };
        assert!(c.validate().unwrap_err()[0].to_string().contains("at most 200000000"));
        let mut c = SparkleConfig::default();
        c.phong.exponent_n = 1.0; // θ = 89.9°: 5e8 visible of 1e9
        assert!(c.validate().unwrap_err()[0].to_string().contains("fewer than"));
    }
}
