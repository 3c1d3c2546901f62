//! The visibility model of §2 and the samplers built on it.
//!
//! A facet at x with unit normal N is seen at time t when N·H_t(x) ≥ cos θ (or
//! |N·H_t(x)| for two-sided facets), H = (L+V)/|L+V| the half vector from x. With a
//! point light or a perspective camera H depends on x, so every sampler below draws the
//! position first and builds the cone around *that position's* H.
//!
//! **Candidates by thinning.** For uniform normals (density 1/4π) a virtual particle's
//! normal falls in a cap of half-angle α with probability (1 - cos α)/2 wherever it is.
//! For a lobe (plates, leaves) the space is cut into cells with a bound f̄ on the normal
//! density over every cap the cell's positions can have; a particle is a candidate with
//! probability q = A(α) f̄ (A the cap's solid angle), its normal is drawn uniformly in
//! the cap and kept with probability f(N)/f̄. Each virtual particle then ends up with
//! a normal in its cap with exactly probability ∫_cap f: the candidates are an exact
//! thinning of the full population, and their count over N virtual particles is
//! binomial. Where q would reach 1 the cell draws normals from f directly instead.
//! (In the periodic box with a lobe, births use adaptively split cells with a Poisson
//! count each and, out in the lobe's tail, normals from f inside a window of angles
//! around the cap instead: `sim::CellTable::split`.)

use glam::Vec3;
use phenomena_core::rng::Stream;
use std::f64::consts::PI;

use crate::config::{LightAt, Population};

/// Extra half-angle added to every candidate cap, radians: covers f32 rounding in the
/// visibility test and in the rotation, so a cap never misses a particle that the test
/// would count as seen (it costs 0.6 % more candidates at θ = 2°).
pub(crate) const CAP_MARGIN_RAD: f64 = 1e-4;

/// Where the eye is, seen from the particles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Eye {
    /// A perspective camera's position.
    Point(Vec3),
    /// An orthographic camera: the unit direction towards the viewer.
    Direction(Vec3),
}

/// Eye and light at one instant: everything the half vector needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Geometry {
    pub(crate) eye: Eye,
    pub(crate) light: LightAt,
}

impl Geometry {
    /// Unit direction from x to the eye.
    #[inline]
    pub(crate) fn eye_dir(&self, x: Vec3) -> Vec3 {
        match self.eye {
            Eye::Point(e) => (e - x).normalize_or_zero(),
            Eye::Direction(d) => d,
        }
    }

    /// Unit direction from x to the light.
    #[inline]
    pub(crate) fn light_dir(&self, x: Vec3) -> Vec3 {
        match self.light {
            LightAt::Direction(d) => d,
            LightAt::Position(p) => (p - x).normalize_or_zero(),
        }
    }

    /// The half vector H at x; `None` where L + V vanishes (the light straight behind
    /// the particle as seen from the eye: no mirror direction exists).
    #[inline]
    pub(crate) fn half_vector(&self, x: Vec3) -> Option<Vec3> {
        (self.light_dir(x) + self.eye_dir(x)).try_normalize()
    }

    /// The eye and the light where they are points at a finite distance (a perspective
    /// camera, a lamp): near them V and L turn quickly.
    pub(crate) fn points(&self) -> impl Iterator<Item = Vec3> {
        let eye = match self.eye {
            Eye::Point(e) => Some(e),
            Eye::Direction(_) => None,
        };
        let lamp = match self.light {
            LightAt::Position(p) => Some(p),
            LightAt::Direction(_) => None,
        };
        eye.into_iter().chain(lamp)
    }

    /// A bound, radians, on the angle between H at the centre and H anywhere within
    /// `radius_m` of it: L + V is Lipschitz with constant g = 1/r_eye + 1/r_light (0 for
    /// a distant one) along segments staying at least r away, and
    /// |a/|a| - b/|b|| ≤ 2|a - b|/|b|. π when the ball reaches the eye or the light.
    pub(crate) fn half_vector_spread(&self, centre: Vec3, radius_m: f32) -> f64 {
        let r = f64::from(radius_m);
        let mut g = 0.0;
        for far in self.points() {
            let d = f64::from((far - centre).length()) - r;
            if !(d > 0.0) {
                return PI;
            }
            g += 1.0 / d;
        }
        let u = f64::from((self.light_dir(centre) + self.eye_dir(centre)).length());
        if !(u > 0.0) {
            return PI;
        }
        let chord = 2.0 * g * r / u;
        if chord >= 2.0 { PI } else { 2.0 * (0.5 * chord).asin() }
    }
}

/// A von Mises-Fisher lobe of normals, density f(N) = C exp(κ (N·A - 1)),
/// C = κ / (2π (1 - e^(-2κ))); κ = 0 is uniform (1/4π).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Lobe {
    pub(crate) kappa: f64,
    norm: f64,
}

impl Lobe {
    pub(crate) fn new(kappa: f64) -> Self {
        let norm = if kappa > 0.0 { kappa / (2.0 * PI * -(-2.0 * kappa).exp_m1()) } else { 1.0 / (4.0 * PI) };
        Self { kappa, norm }
    }

    /// κ for a tilt spread σ (degrees): the lobe's tilt has standard deviation ≈ σ per axis
    /// for small σ (κ = 1/σ²).
    pub(crate) fn from_spread_deg(spread_deg: f32) -> Self {
        let s = f64::from(spread_deg).to_radians();
        Self::new(1.0 / (s * s))
    }

    pub(crate) fn is_uniform(&self) -> bool {
        self.kappa == 0.0
    }

    /// Density at cos(angle to the axis) = `c`, per steradian.
    #[inline]
    pub(crate) fn density(&self, c: f64) -> f64 {
        if self.kappa > 0.0 { self.norm * (self.kappa * (c - 1.0)).exp() } else { self.norm }
    }

    /// Probability that a normal of the lobe makes a cosine in `w_lo..=w_hi` with the axis:
    /// 2π C/κ (e^{κ(w_hi - 1)} - e^{κ(w_lo - 1)}) (uniform: (w_hi - w_lo)/2).
    pub(crate) fn polar_mass(&self, w_lo: f64, w_hi: f64) -> f64 {
        if self.kappa > 0.0 {
            2.0 * PI * self.norm / self.kappa
                * ((self.kappa * (w_hi - 1.0)).exp() - (self.kappa * (w_lo - 1.0)).exp())
        } else {
            0.5 * (w_hi - w_lo)
        }
    }

    /// The cosine to the axis of a normal drawn from the lobe restricted to cosines in
    /// `w_lo..=w_hi`, from a uniform `u` (inversion of the CDF ∝ e^{κ w}; uniform: linear).
    #[inline]
    pub(crate) fn polar_in(&self, w_lo: f64, w_hi: f64, u: f64) -> f64 {
        let w = if self.kappa > 0.0 {
            w_hi + (u + (1.0 - u) * (-self.kappa * (w_hi - w_lo)).exp()).ln() / self.kappa
        } else {
            w_lo + u * (w_hi - w_lo)
        };
        w.clamp(w_lo, w_hi)
    }

    /// A normal drawn from the lobe around `axis` (Wood's inversion for the 3-D case).
    pub(crate) fn sample(&self, axis: Vec3, rng: &mut Stream) -> Vec3 {
        let u = rng.next_f64();
        let w = if self.kappa > 0.0 {
            (1.0 + (u + (1.0 - u) * (-2.0 * self.kappa).exp()).ln() / self.kappa).clamp(-1.0, 1.0)
        } else {
            2.0 * u - 1.0
        };
        around(axis, w, rng)
    }
}

/// A uniformly distributed unit vector of the plane, (cos φ, sin φ) for φ uniform, by
/// rejection from the square (no trigonometry: 1.27 tries on average).
#[inline]
pub(crate) fn unit_circle(rng: &mut Stream) -> (f32, f32) {
    loop {
        let (a, b) = (2.0 * rng.next_f32() - 1.0, 2.0 * rng.next_f32() - 1.0);
        let r2 = a * a + b * b;
        if r2 <= 1.0 && r2 > 1e-12 {
            let inv = 1.0 / r2.sqrt();
            return (a * inv, b * inv);
        }
    }
}

/// A unit vector at cosine `w` from `axis`, at a uniformly random azimuth.
#[inline]
pub(crate) fn around(axis: Vec3, w: f64, rng: &mut Stream) -> Vec3 {
    let (e1, e2) = axis.any_orthonormal_pair();
    let s = (1.0 - w * w).max(0.0).sqrt() as f32;
    let (c, d) = unit_circle(rng);
    // Unit up to rounding: one Newton step toward length 1 instead of a normalisation.
    let p = axis * w as f32 + (e1 * c + e2 * d) * s;
    p * (1.5 - 0.5 * p.length_squared())
}

/// A unit vector uniformly distributed in the cap of half-angle α around `axis`, with
/// `one_minus_cos` = 1 - cos α (passed to keep precision for tiny caps).
#[inline]
pub(crate) fn in_cap(axis: Vec3, one_minus_cos: f64, rng: &mut Stream) -> Vec3 {
    around(axis, 1.0 - rng.next_f64() * one_minus_cos, rng)
}

/// 1 - cos α without cancellation.
pub(crate) fn one_minus_cos(alpha: f64) -> f64 {
    let s = (0.5 * alpha.min(PI)).sin();
    2.0 * s * s
}

/// Where particles live.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Space {
    /// A periodic box (diamond dust): what leaves one face re-enters at the opposite one.
    Box { min: Vec3, size: Vec3 },
    /// The surface of a hemisphere rising along +y (leaf glitter).
    Dome { centre: Vec3, radius: f32 },
}

/// Cells per axis of the box, and (azimuth, height) cells of the dome, for lobe bounds.
const BOX_CELLS: usize = 16;
const DOME_CELLS: (usize, usize) = (64, 16);

impl Space {
    pub(crate) fn of(population: &Population) -> Self {
        match population {
            Population::DiamondDust(d) => Space::Box { min: d.box_min_m, size: d.box_max_m - d.box_min_m },
            Population::LeafGlitter(l) => Space::Dome { centre: l.centre_m, radius: l.radius_m },
        }
    }

    /// Number of equal-measure cells (`lobe` uniform: one cell, no bound needed).
    pub(crate) fn cell_count(&self, uniform: bool) -> usize {
        match (uniform, self) {
            (true, _) => 1,
            (false, Space::Box { .. }) => BOX_CELLS.pow(3),
            (false, Space::Dome { .. }) => DOME_CELLS.0 * DOME_CELLS.1,
        }
    }

    /// A uniformly distributed point of cell `c` of `cells` (volume or area measure).
    #[inline]
    pub(crate) fn sample_in_cell(&self, c: usize, cells: usize, rng: &mut Stream) -> Vec3 {
        let (u, v, w) = (rng.next_f32(), rng.next_f32(), rng.next_f32());
        match *self {
            Space::Box { min, size } => {
                if cells == 1 {
                    return min + size * Vec3::new(u, v, w);
                }
                let n = BOX_CELLS;
                let (i, j, k) = (c % n, (c / n) % n, c / (n * n));
                let f = Vec3::new(i as f32 + u, j as f32 + v, k as f32 + w) / n as f32;
                min + size * f
            }
            Space::Dome { centre, radius } => {
                let (na, nh) = if cells == 1 { (1, 1) } else { DOME_CELLS };
                let (ia, ih) = (c % na, c / na);
                let z = (ih as f32 + v) / nh as f32;
                let phi = std::f32::consts::TAU * (ia as f32 + u) / na as f32;
                let s = (1.0 - z * z).max(0.0).sqrt();
                let _ = w;
                centre + radius * Vec3::new(s * phi.cos(), z, s * phi.sin())
            }
        }
    }

    /// Bounding ball (centre, radius) of cell `c`, and a bound (radians) on the angle
    /// between the lobe axis at its centre and anywhere in it (0 for a fixed axis).
    pub(crate) fn cell_bounds(&self, c: usize, cells: usize) -> (Vec3, f32, f64) {
        match *self {
            Space::Box { min, size } => {
                if cells == 1 {
                    return (min + 0.5 * size, 0.5 * size.length(), 0.0);
                }
                let n = BOX_CELLS;
                let (i, j, k) = (c % n, (c / n) % n, c / (n * n));
                let cell = size / n as f32;
                let centre = min + cell * Vec3::new(i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5);
                (centre, 0.5 * cell.length(), 0.0)
            }
            Space::Dome { centre, radius } => {
                let (na, nh) = if cells == 1 { (1, 1) } else { DOME_CELLS };
                let (ia, ih) = (c % na, c / na);
                let (z0, z1) = (ih as f64 / nh as f64, (ih + 1) as f64 / nh as f64);
                let (p0, p1) = (z1.acos(), z0.acos()); // polar angles, p0 < p1
                let dphi = 2.0 * PI / na as f64;
                let pm = 0.5 * (p0 + p1);
                let phim = (ia as f64 + 0.5) * dphi;
                // Arc from the centre point: along the meridian, then along a parallel of
                // radius at most sin(p1): a bound on the angle to any point of the patch.
                let arc = if cells == 1 { PI } else { 0.5 * (p1 - p0) + 0.5 * dphi * p1.sin() };
                let c3 = centre
                    + radius
                        * Vec3::new(
                            (pm.sin() * phim.cos()) as f32,
                            pm.cos() as f32,
                            (pm.sin() * phim.sin()) as f32,
                        );
                (c3, radius * arc as f32 * 1.001, arc)
            }
        }
    }

    /// Wrap a position into the periodic box (the dome does not move).
    #[inline]
    pub(crate) fn wrap(&self, x: Vec3) -> Vec3 {
        match *self {
            Space::Box { min, size } => {
                let mut r = (x - min).to_array();
                for (v, s) in r.iter_mut().zip(size.to_array()) {
                    // One frame's step is far smaller than the box: the common case is
                    // no wrap or one; rem_euclid handles anything else.
                    if *v < 0.0 {
                        *v += s;
                    } else if *v >= s {
                        *v -= s;
                    }
                    if !(*v >= 0.0 && *v < s) {
                        *v = v.rem_euclid(s);
                        // rem_euclid may round up to `s` itself for tiny negative inputs.
                        if *v >= s {
                            *v = 0.0;
                        }
                    }
                }
                min + Vec3::from(r)
            }
            Space::Dome { .. } => x,
        }
    }

    /// The lobe axis at x: fixed (`Some`) or the dome's outward normal.
    #[inline]
    pub(crate) fn radial_axis(&self, x: Vec3) -> Vec3 {
        match *self {
            Space::Dome { centre, .. } => (x - centre).normalize_or(Vec3::Y),
            Space::Box { .. } => Vec3::Y,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use phenomena_core::rng::Purpose;

    const P: Purpose = Purpose::named("test.sparkle.model");

    #[test]
    fn lobe_sampler_matches_its_density() {
        // Mean of N·A under vMF is coth κ - 1/κ; under uniform 0. Tolerance: 5 standard
        // errors (the variance of N·A is at most 1).
        let mut rng = Stream::new(1, P, 0);
        for kappa in [0.0, 2.0, 50.0, 13_000.0] {
            let lobe = Lobe::new(kappa);
            let m = 40_000;
            let mean = (0..m).map(|_| f64::from(lobe.sample(Vec3::Y, &mut rng).y)).sum::<f64>() / m as f64;
            let expect = if kappa > 0.0 { 1.0 / kappa.tanh() - 1.0 / kappa } else { 0.0 };
            assert!((mean - expect).abs() < 5.0 / (m as f64).sqrt(), "κ {kappa}: {mean} vs {expect}");
        }
        // The density integrates to 1 over the sphere: 2π ∫ f(c) dc on [-1, 1].
        for kappa in [0.0, 3.0, 400.0] {
            let lobe = Lobe::new(kappa);
            let k = 200_000;
            let sum: f64 = (0..k).map(|i| lobe.density(-1.0 + 2.0 * (i as f64 + 0.5) / k as f64)).sum();
            assert!((sum * 2.0 / k as f64 * 2.0 * PI - 1.0).abs() < 1e-3, "κ {kappa}");
        }
    }

    #[test]
    fn cap_sampler_stays_in_the_cap_and_is_uniform_in_cosine() {
        let mut rng = Stream::new(2, P, 0);
        let axis = Vec3::new(0.3, -0.2, 0.9).normalize();
        let alpha = 0.05f64;
        let omc = one_minus_cos(alpha);
        let m = 20_000;
        let mut mean = 0.0;
        for _ in 0..m {
            let n = in_cap(axis, omc, &mut rng);
            let c = f64::from(n.dot(axis));
            assert!(c >= 1.0 - omc - 1e-6);
            mean += (1.0 - c) / omc;
        }
        // (1 - cos)/(1 - cos α) is uniform on [0, 1]: mean 1/2, sd 1/√12.
        mean /= m as f64;
        assert!((mean - 0.5).abs() < 5.0 / (12.0 * m as f64).sqrt(), "{mean}");
    }

    #[test]
    fn half_vector_spread_bounds_the_truth() {
        // Sample points in the ball and check the measured angle never exceeds the bound.
        let g = Geometry { eye: Eye::Point(Vec3::ZERO), light: LightAt::Position(Vec3::new(5.0, 5.0, -5.0)) };
        let mut rng = Stream::new(3, P, 0);
        for _ in 0..200 {
            let centre = Vec3::new(rng.uniform(-8.0, 8.0), rng.uniform(-8.0, 8.0), rng.uniform(-20.0, -3.0));
            let r = rng.uniform(0.01, 1.0);
            let bound = g.half_vector_spread(centre, r);
            let Some(h0) = g.half_vector(centre) else { continue };
            for _ in 0..50 {
                let (x, y) = rng.in_unit_disk();
                let p = centre + r * Vec3::new(x, y, rng.uniform(-1.0, 1.0)).clamp_length_max(1.0);
                if let Some(h) = g.half_vector(p) {
                    let ang = f64::from(h.dot(h0).clamp(-1.0, 1.0)).acos();
                    assert!(ang <= bound + 1e-3, "{ang} > {bound}");
                }
            }
        }
    }

    #[test]
    fn wrap_keeps_points_in_the_box() {
        let s = Space::Box { min: Vec3::new(-1.0, 0.0, -2.0), size: Vec3::new(2.0, 1.0, 2.0) };
        for x in [Vec3::new(1.5, -0.25, 0.5), Vec3::new(-1.0 - 1e-9, 1.0, -2.0), Vec3::new(-7.0, 3.5, 9.0)] {
            let w = s.wrap(x);
            assert!(
                w.cmpge(Vec3::new(-1.0, 0.0, -2.0)).all() && w.cmplt(Vec3::new(1.0, 1.0, 0.0)).all(),
                "{w}"
            );
        }
        assert_eq!(s.wrap(Vec3::new(1.5, -0.25, 0.5)), Vec3::new(-0.5, 0.75, -1.5));
    }

    #[test]
    fn dome_cells_cover_their_patch() {
        let s = Space::Dome { centre: Vec3::new(1.0, 0.0, -3.0), radius: 2.0 };
        let cells = s.cell_count(false);
        let mut rng = Stream::new(4, P, 0);
        for c in 0..cells {
            let (centre, r, arc) = s.cell_bounds(c, cells);
            for _ in 0..20 {
                let x = s.sample_in_cell(c, cells, &mut rng);
                assert!((x - centre).length() <= r, "cell {c}");
                let ang = f64::from(s.radial_axis(x).dot(s.radial_axis(centre)).clamp(-1.0, 1.0)).acos();
                assert!(ang <= arc + 1e-3, "cell {c}: {ang} > {arc}");
            }
        }
    }
}
