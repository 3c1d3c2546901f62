//! SPH smoothing kernels in 2-D and 3-D, each normalised so that ∫W = 1.
//!
//! Every kernel here is parameterised by its *support radius* `d`: W(r) = 0 for r > d.
//! Gradients are returned as a factor `g` with ∇W(r⃗) = g · r⃗, which works for any
//! dimension and lets callers keep their own vector type.
//!
//! | kernel | 3-D normalisation | 2-D normalisation | source |
//! | --- | --- | --- | --- |
//! | poly6 | 315 / (64π d⁹) | 4 / (π d⁸) | flame paper eq (2); aurora thesis eq (2.12) |
//! | spiky | 15 / (π d⁶) | 10 / (π d⁵) | Müller et al. 2003; aurora thesis eq (2.15)-(2.16) |
//! | cubic spline | 8 / (π d³) | 40 / (7π d²) | Monaghan 1992; aurora thesis eq (2.17)-(2.18) with h = d/2 |

use serde::{Deserialize, Serialize};
use wide::f32x8;

/// Which kernel function.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum KernelKind {
    /// W = σ (d² − r²)³. Smooth, no square root; its gradient vanishes at r = 0, so it
    /// lets particles cluster when used for pressure.
    Poly6,
    /// W = σ (d − r)³. Its gradient stays finite and non-zero as r → 0, the usual
    /// choice for pressure forces.
    Spiky,
    /// Monaghan's M4 cubic B-spline with smoothing length h = d/2.
    CubicSpline,
}

/// Spatial dimension of a kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Dim {
    /// Two dimensions (e.g. the aurora's x-z plane).
    Two,
    /// Three dimensions.
    Three,
}

/// A normalised SPH kernel with a fixed support radius.
///
/// Stored in scaled form, W(r) = σ/d^D · f(r/d) with σ the dimensionless factor of the
/// table above: the coefficients stay representable in f32 for any support radius from
/// 1e-6 to 1e6 (a literal 315/(64π d⁹) overflows below d ≈ 5.6e-5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    kind: KernelKind,
    dim: Dim,
    support: f32,
    support_sq: f32,
    inv_support: f32,
    inv_support_sq: f32,
    /// σ / d^D: the value scale.
    value_scale: f32,
    /// σ / d^(D+1): the derivative scale (dW/dr = this × f'(q)).
    deriv_scale: f32,
}

impl Kernel {
    /// A kernel of `kind` in `dim` dimensions with support radius `support` (> 0).
    /// A non-positive or non-finite support yields a kernel that is zero everywhere
    /// (callers validate their configuration first).
    pub fn new(kind: KernelKind, dim: Dim, support: f32) -> Self {
        use std::f64::consts::PI;
        let valid = support > 0.0 && support.is_finite();
        let d = if valid { f64::from(support) } else { 1.0 };
        // Dimensionless factors σ with W = σ/d^D f(q), q = r/d.
        let (sigma, power) = match (kind, dim) {
            (KernelKind::Poly6, Dim::Three) => (315.0 / (64.0 * PI), 3),
            (KernelKind::Poly6, Dim::Two) => (4.0 / PI, 2),
            (KernelKind::Spiky, Dim::Three) => (15.0 / PI, 3),
            (KernelKind::Spiky, Dim::Two) => (10.0 / PI, 2),
            (KernelKind::CubicSpline, Dim::Three) => (8.0 / PI, 3),
            (KernelKind::CubicSpline, Dim::Two) => (40.0 / (7.0 * PI), 2),
        };
        let scale = if valid { sigma / d.powi(power) } else { 0.0 };
        Self {
            kind,
            dim,
            support: d as f32,
            support_sq: (d * d) as f32,
            inv_support: (1.0 / d) as f32,
            inv_support_sq: (1.0 / (d * d)) as f32,
            value_scale: scale as f32,
            deriv_scale: (scale / d) as f32,
        }
    }

    /// The kernel kind.
    pub fn kind(&self) -> KernelKind {
        self.kind
    }

    /// The dimension.
    pub fn dim(&self) -> Dim {
        self.dim
    }

    /// Support radius d.
    pub fn support(&self) -> f32 {
        self.support
    }

    /// W(r) for distance `r` ≥ 0.
    #[inline]
    pub fn value(&self, r: f32) -> f32 {
        if !(r < self.support) {
            return 0.0;
        }
        let q = r * self.inv_support;
        match self.kind {
            KernelKind::Poly6 => {
                let t = 1.0 - q * q;
                self.value_scale * t * t * t
            }
            KernelKind::Spiky => {
                let t = 1.0 - q;
                self.value_scale * t * t * t
            }
            KernelKind::CubicSpline => self.value_scale * spline_shape(q),
        }
    }

    /// W from the squared distance, without a branch, so it can be summed over every
    /// candidate of a neighbour search, inside the support or not: exactly 0 outside, and
    /// for NaN or infinite input. Poly6 needs no square root.
    #[inline]
    pub fn value_sq(&self, r_sq: f32) -> f32 {
        match self.kind {
            KernelKind::Poly6 => {
                let t = (1.0 - r_sq * self.inv_support_sq).max(0.0);
                self.value_scale * t * t * t
            }
            KernelKind::Spiky => {
                let t = (1.0 - r_sq.sqrt() * self.inv_support).max(0.0);
                self.value_scale * t * t * t
            }
            KernelKind::CubicSpline => self.value_scale * spline_shape(r_sq.sqrt() * self.inv_support),
        }
    }

    /// dW/dr at distance `r` ≥ 0.
    #[inline]
    pub fn derivative(&self, r: f32) -> f32 {
        if !(r < self.support) {
            return 0.0;
        }
        let q = r * self.inv_support;
        match self.kind {
            KernelKind::Poly6 => {
                let t = 1.0 - q * q;
                -6.0 * self.deriv_scale * q * t * t
            }
            KernelKind::Spiky => {
                let t = 1.0 - q;
                -3.0 * self.deriv_scale * t * t
            }
            KernelKind::CubicSpline => self.deriv_scale * spline_shape_derivative(q),
        }
    }

    /// The factor g with ∇W(r⃗) = g · r⃗, for `r = |r⃗|`. Zero at r = 0, where the
    /// direction is undefined (a coincident pair exerts no force on each other).
    #[inline]
    pub fn gradient_factor(&self, r: f32) -> f32 {
        if !(r > 0.0) || !(r < self.support) {
            return 0.0;
        }
        match self.kind {
            // Avoid the division: (dW/dr)/r = -6 σ/d^(D+2) (1 - q²)².
            KernelKind::Poly6 => {
                let q = r * self.inv_support;
                let t = 1.0 - q * q;
                -6.0 * self.deriv_scale * self.inv_support * t * t
            }
            _ => self.derivative(r) / r,
        }
    }
    /// [`Self::gradient_factor`] from the squared distance, without a branch (for loops
    /// over every candidate): 0 at r = 0, outside the support, and for NaN or infinite
    /// input.
    #[inline]
    pub fn gradient_factor_sq(&self, r_sq: f32) -> f32 {
        let inside = r_sq > 0.0 && r_sq < self.support_sq;
        let g = match self.kind {
            KernelKind::Poly6 => {
                let t = 1.0 - r_sq * self.inv_support_sq;
                -6.0 * self.deriv_scale * self.inv_support * t * t
            }
            KernelKind::Spiky => {
                let r = r_sq.sqrt();
                let t = 1.0 - r * self.inv_support;
                -3.0 * self.deriv_scale * t * t / r
            }
            KernelKind::CubicSpline => {
                // Inner piece 6(3q² - 2q)/r = 6(3q - 2)/d: no division there.
                let r = r_sq.sqrt();
                let q = r * self.inv_support;
                let inner = 6.0 * self.inv_support * (3.0 * q - 2.0);
                let t = 1.0 - q;
                let outer = -6.0 * t * t / r;
                self.deriv_scale * if q <= 0.5 { inner } else { outer }
            }
        };
        if inside { g } else { 0.0 }
    }

    /// [`Self::value_sq`] on eight squared distances at once, bit-identical to it lane by
    /// lane for finite input (the same IEEE operations in the same order).
    #[inline]
    pub fn value_sq_x8(&self, r_sq: f32x8) -> f32x8 {
        let one = f32x8::splat(1.0);
        let zero = f32x8::ZERO;
        let scale = f32x8::splat(self.value_scale);
        match self.kind {
            KernelKind::Poly6 => {
                let t = (one - r_sq * f32x8::splat(self.inv_support_sq)).max(zero);
                scale * t * t * t
            }
            KernelKind::Spiky => {
                let t = (one - r_sq.sqrt() * f32x8::splat(self.inv_support)).max(zero);
                scale * t * t * t
            }
            KernelKind::CubicSpline => {
                let q = r_sq.sqrt() * f32x8::splat(self.inv_support);
                let inner = f32x8::splat(6.0) * (q * q * q - q * q) + one;
                let t = (one - q).max(zero);
                let outer = f32x8::splat(2.0) * t * t * t;
                scale * q.simd_le(f32x8::splat(0.5)).select(inner, outer)
            }
        }
    }

    /// [`Self::gradient_factor_sq`] on eight squared distances at once, bit-identical to
    /// it lane by lane for finite input.
    #[inline]
    pub fn gradient_factor_sq_x8(&self, r_sq: f32x8) -> f32x8 {
        let one = f32x8::splat(1.0);
        let inside = r_sq.simd_gt(f32x8::ZERO) & r_sq.simd_lt(f32x8::splat(self.support_sq));
        let ds = f32x8::splat(self.deriv_scale);
        let inv_d = f32x8::splat(self.inv_support);
        let g = match self.kind {
            KernelKind::Poly6 => {
                let t = one - r_sq * f32x8::splat(self.inv_support_sq);
                f32x8::splat(-6.0) * ds * inv_d * t * t
            }
            KernelKind::Spiky => {
                let r = r_sq.sqrt();
                let t = one - r * inv_d;
                f32x8::splat(-3.0) * ds * t * t / r
            }
            KernelKind::CubicSpline => {
                let r = r_sq.sqrt();
                let q = r * inv_d;
                let inner = f32x8::splat(6.0) * inv_d * (f32x8::splat(3.0) * q - f32x8::splat(2.0));
                let t = one - q;
                let outer = f32x8::splat(-6.0) * t * t / r;
                ds * q.simd_le(f32x8::splat(0.5)).select(inner, outer)
            }
        };
        inside.select(g, f32x8::ZERO)
    }
}

/// Cubic spline shape in terms of q = r/d ∈ [0, 1] (h = d/2, so q_h = 2q).
#[inline]
fn spline_shape(q: f32) -> f32 {
    // Both pieces computed, one selected: no unpredictable branch in neighbour loops.
    let inner = 6.0 * (q * q * q - q * q) + 1.0;
    let t = (1.0 - q).max(0.0);
    let outer = 2.0 * t * t * t;
    if q <= 0.5 { inner } else { outer }
}

#[inline]
fn spline_shape_derivative(q: f32) -> f32 {
    let inner = 6.0 * (3.0 * q * q - 2.0 * q);
    let t = (1.0 - q).max(0.0);
    let outer = -6.0 * t * t;
    if q <= 0.5 { inner } else { outer }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    const KINDS: [KernelKind; 3] = [KernelKind::Poly6, KernelKind::Spiky, KernelKind::CubicSpline];

    /// Radial integral ∫W dV by composite Simpson's rule in f64 on the f32 kernel.
    fn radial_integral(k: &Kernel) -> f64 {
        let n = 20_000;
        let d = f64::from(k.support());
        let h = d / n as f64;
        let mut sum = 0.0;
        for i in 0..=n {
            let r = i as f64 * h;
            let shell = match k.dim() {
                Dim::Two => 2.0 * std::f64::consts::PI * r,
                Dim::Three => 4.0 * std::f64::consts::PI * r * r,
            };
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            sum += w * shell * f64::from(k.value(r as f32));
        }
        sum * h / 3.0
    }

    #[test]
    fn kernels_integrate_to_one() {
        // ∫W = 1 within 1e-3. Simpson's error at 20,000 intervals is far below
        // that; the remaining error is f32 rounding of W (relative ~1e-7).
        for kind in KINDS {
            for dim in [Dim::Two, Dim::Three] {
                for support in [0.035_f32, 1.0, 4.0] {
                    let k = Kernel::new(kind, dim, support);
                    let integral = radial_integral(&k);
                    assert!((integral - 1.0).abs() < 1e-3, "{kind:?} {dim:?} d={support}: {integral}");
                }
            }
        }
    }

    #[test]
    fn kernels_integrate_to_one_on_a_cartesian_grid() {
        // An independent check of the 3-D normalisation by a midpoint sum over a lattice
        // (no radial symmetry assumed). Error of the midpoint rule with 60 samples per
        // support radius on these smooth kernels is ~1e-4; spiky has a kink at r = 0.
        for kind in KINDS {
            let k = Kernel::new(kind, Dim::Three, 1.0);
            let n = 60;
            let h = 1.0 / n as f64;
            let mut sum = 0.0;
            for i in -n..n {
                for j in -n..n {
                    for l in -n..n {
                        let p = [(i as f64 + 0.5) * h, (j as f64 + 0.5) * h, (l as f64 + 0.5) * h];
                        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                        sum += f64::from(k.value(r as f32));
                    }
                }
            }
            let integral = sum * h * h * h;
            assert!((integral - 1.0).abs() < 1e-3, "{kind:?}: {integral}");
        }
    }

    #[test]
    fn derivative_matches_finite_differences() {
        for kind in KINDS {
            for dim in [Dim::Two, Dim::Three] {
                let k = Kernel::new(kind, dim, 2.0);
                for i in 1..40 {
                    let r = i as f32 * 0.049;
                    let eps = 1e-3_f32;
                    let fd = (k.value(r + eps) - k.value(r - eps)) / (2.0 * eps);
                    let an = k.derivative(r);
                    let scale = k.value(0.0).abs().max(1e-6);
                    // Central difference error O(eps² W''') plus f32 cancellation.
                    assert!((fd - an).abs() / scale < 2e-3, "{kind:?} r={r}: fd {fd} an {an}");
                    assert!((k.gradient_factor(r) * r - an).abs() / scale < 1e-5);
                }
            }
        }
    }

    #[test]
    fn squared_distance_forms_agree_with_the_plain_ones() {
        // Same formulas, rearranged (the spline's inner gradient without the division):
        // a few f32 roundings apart, relative 1e-5 of the kernel's scale at r = 0.
        for kind in KINDS {
            for dim in [Dim::Two, Dim::Three] {
                let k = Kernel::new(kind, dim, 0.35);
                let (w0, g0) = (k.value(0.0), k.derivative(0.0).abs().max(k.gradient_factor(0.01).abs()));
                for i in 0..=400 {
                    let r = i as f32 * 0.001;
                    assert!((k.value_sq(r * r) - k.value(r)).abs() <= 1e-5 * w0, "{kind:?} {dim:?} W r={r}");
                    let (a, b) = (k.gradient_factor_sq(r * r), k.gradient_factor(r));
                    assert!((a - b).abs() <= 1e-5 * g0 + 1e-5 * b.abs(), "{kind:?} {dim:?} g r={r}: {a} {b}");
                }
            }
        }
    }

    #[test]
    fn eight_lane_forms_are_bit_identical_to_the_scalar_ones() {
        for kind in KINDS {
            for dim in [Dim::Two, Dim::Three] {
                let k = Kernel::new(kind, dim, 0.35);
                for c in 0..100 {
                    // Squared distances from 0 to past the support, exact 0 included.
                    let r_sq: [f32; 8] = std::array::from_fn(|l| ((c * 8 + l) as f32 * 0.000_2).powi(2));
                    let w = k.value_sq_x8(f32x8::from(r_sq)).to_array();
                    let g = k.gradient_factor_sq_x8(f32x8::from(r_sq)).to_array();
                    for l in 0..8 {
                        assert_eq!(w[l].to_bits(), k.value_sq(r_sq[l]).to_bits(), "{kind:?} W {}", r_sq[l]);
                        assert_eq!(
                            g[l].to_bits(),
                            k.gradient_factor_sq(r_sq[l]).to_bits(),
                            "{kind:?} g {}",
                            r_sq[l]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn thesis_spline_gradient_agrees() {
        // Aurora thesis eq (2.18), h = d/2: ∇W = 45/(14π h⁴) (q_h - 4/3) r⃗ for q_h < 1.
        let d = 2.0_f32;
        let h = d / 2.0;
        let k = Kernel::new(KernelKind::CubicSpline, Dim::Two, d);
        let r = 0.6_f32;
        let q = r / h;
        let thesis = 45.0 / (14.0 * PI * h.powi(4)) * (q - 4.0 / 3.0);
        assert!((k.gradient_factor(r) - thesis).abs() < 1e-5 * thesis.abs());
        let thesis_w = 10.0 / (7.0 * PI * h * h) * (1.0 - 1.5 * q * q + 0.75 * q * q * q);
        assert!((k.value(r) - thesis_w).abs() < 1e-6);
    }

    #[test]
    fn zero_outside_support_and_for_nan() {
        for kind in KINDS {
            let k = Kernel::new(kind, Dim::Three, 1.0);
            assert_eq!(k.value(1.0), 0.0);
            assert_eq!(k.value(5.0), 0.0);
            assert_eq!(k.value(f32::NAN), 0.0);
            assert_eq!(k.gradient_factor(0.0), 0.0);
            assert_eq!(k.value_sq(1.5), 0.0);
            assert_eq!(k.value_sq(f32::NAN), 0.0);
            assert_eq!(k.value_sq(f32::INFINITY), 0.0);
            for bad in [0.0, 1.0, 1.5, f32::NAN, f32::INFINITY] {
                assert_eq!(k.gradient_factor_sq(bad), 0.0, "{kind:?} {bad}");
            }
        }
    }

    #[test]
    fn tiny_and_huge_supports_stay_finite_and_normalised() {
        // 315/(64π d⁹) would overflow f32 below d ≈ 5.6e-5; the scaled form does not.
        for support in [1e-6_f32, 4e-5, 1e5] {
            for kind in KINDS {
                for dim in [Dim::Two, Dim::Three] {
                    let k = Kernel::new(kind, dim, support);
                    assert!(k.value(0.0).is_finite() && k.value(0.0) > 0.0, "{kind:?} {dim:?} {support}");
                    let integral = radial_integral(&k);
                    assert!((integral - 1.0).abs() < 1e-3, "{kind:?} {dim:?} d={support}: {integral}");
                }
            }
        }
    }
}
