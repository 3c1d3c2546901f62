//! Colour science shared by every phenomenon: CIE colour-matching functions, spectral
//! lines, Planck's law, XYZ <-> linear sRGB and the sRGB transfer function.
//!
//! All spectral work is done in `f64`; the embedded tables are the CIE data at 1 nm
//! (see `tools/gen_cie_tables.py` for their provenance).

use glam::DVec3;

use crate::cmf_data::{CIE1931_2DEG, CIE1931_2DEG_START_NM, CIE2015_2DEG, CIE2015_2DEG_START_NM};

/// Planck constant h in J·s (CODATA 2018, exact in the SI).
pub const PLANCK_J_S: f64 = 6.626_070_15e-34;
/// Speed of light in vacuum c in m/s (exact in the SI).
pub const LIGHT_SPEED_M_PER_S: f64 = 299_792_458.0;
/// Boltzmann constant k in J/K (CODATA 2018, exact in the SI).
pub const BOLTZMANN_J_PER_K: f64 = 1.380_649e-23;

/// A CIE standard colorimetric observer, tabulated at 1 nm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Observer {
    /// CIE 1931 2° standard observer, 360-830 nm (used by the flame paper, eq 14-16).
    Cie1931TwoDegree,
    /// CIE 2015 2° XYZ functions (the CIE 2006 physiological observer transformed to
    /// XYZ), 390-830 nm; the aurora thesis's Table 2.1 uses these values.
    Cie2015TwoDegree,
}

impl Observer {
    fn table(self) -> (u32, &'static [[f32; 3]]) {
        match self {
            Observer::Cie1931TwoDegree => (CIE1931_2DEG_START_NM, &CIE1931_2DEG[..]),
            Observer::Cie2015TwoDegree => (CIE2015_2DEG_START_NM, &CIE2015_2DEG[..]),
        }
    }

    /// The tabulated wavelength range in nm, inclusive at both ends.
    pub fn range_nm(self) -> (u32, u32) {
        let (start, table) = self.table();
        (start, start + table.len() as u32 - 1)
    }

    /// The colour-matching functions (x̄, ȳ, z̄) at `wavelength_nm`, linearly interpolated
    /// between the 1 nm samples; zero outside the tabulated range.
    pub fn cmf(self, wavelength_nm: f64) -> DVec3 {
        let (start, table) = self.table();
        let t = wavelength_nm - f64::from(start);
        if !(t >= 0.0) || t > (table.len() - 1) as f64 {
            return DVec3::ZERO;
        }
        let i = (t.floor() as usize).min(table.len() - 1);
        let frac = t - i as f64;
        let a = to_dvec3(table[i]);
        if frac == 0.0 {
            return a;
        }
        let b = to_dvec3(table[i + 1]);
        a + (b - a) * frac
    }

    /// The tabulated samples as `(wavelength_nm, x̄ȳz̄)` pairs, 1 nm apart.
    pub fn samples(self) -> impl Iterator<Item = (f64, DVec3)> {
        let (start, table) = self.table();
        table.iter().enumerate().map(move |(i, v)| (f64::from(start) + i as f64, to_dvec3(*v)))
    }
}

fn to_dvec3(v: [f32; 3]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
}

/// XYZ tristimulus of a monochromatic spectral line of radiant power `power` at
/// `wavelength_nm` (X = P·x̄(λ), and likewise for Y and Z).
///
/// This is the per-line conversion of the aurora thesis §2.4.3 (Table 2.1 lists exactly
/// these x̄ȳz̄ values for the CIE 2015 2° observer).
pub fn spectral_line_xyz(observer: Observer, wavelength_nm: f64, power: f64) -> DVec3 {
    observer.cmf(wavelength_nm) * power
}

/// Planck's law as printed in the flame paper, eq (13): spectral exitance of a black
/// body, I(λ, T) = 2πhc² / λ⁵ / (exp(hc / λkT) - 1), in W·m⁻²·nm⁻¹.
///
/// Safe for every finite temperature: where the exponent exceeds the range of `f64`
/// (very cold bodies at visible wavelengths) the result is exactly 0, never NaN.
/// Non-positive or non-finite inputs give 0.
pub fn planck_exitance(wavelength_nm: f64, temperature_k: f64) -> f64 {
    let valid = wavelength_nm > 0.0 && temperature_k > 0.0;
    if !valid || !wavelength_nm.is_finite() || !temperature_k.is_finite() {
        return 0.0;
    }
    let lambda_m = wavelength_nm * 1e-9;
    let exponent = PLANCK_J_S * LIGHT_SPEED_M_PER_S / (lambda_m * BOLTZMANN_J_PER_K * temperature_k);
    // exp overflows f64 above ~709.78; the radiance there is below 1e-300 of its peak.
    if exponent > 700.0 {
        return 0.0;
    }
    let c1 = 2.0 * std::f64::consts::PI * PLANCK_J_S * LIGHT_SPEED_M_PER_S * LIGHT_SPEED_M_PER_S;
    let per_metre = c1 / lambda_m.powi(5) / exponent.exp_m1();
    per_metre * 1e-9
}

/// Blackbody XYZ by the flame paper's eq (14)-(16): X = (1/c)∫ I(λ,T) x̄(λ) dλ with
/// c = ∫ ȳ(λ) dλ, as a 1 nm rectangle-rule sum over the observer's whole table.
///
/// The paper integrates over 360-800 nm; the CIE 1931 table runs to 830 nm. The
/// functions are below 1.3e-4 of their peaks past 800 nm, so the chromaticity moves by
/// less than 1e-5 (measured against colour-science, `tests/data/README.md`).
///
/// Returns zero for temperatures with no visible emission (e.g. 1 K), never NaN.
pub fn blackbody_xyz(observer: Observer, temperature_k: f64) -> DVec3 {
    let mut sum = DVec3::ZERO;
    let mut y_norm = 0.0;
    for (lambda, cmf) in observer.samples() {
        sum += cmf * planck_exitance(lambda, temperature_k);
        y_norm += cmf.y;
    }
    sum / y_norm
}

/// CIE xy chromaticity of an XYZ colour, or `None` for black (X+Y+Z = 0).
pub fn xy_chromaticity(xyz: DVec3) -> Option<(f64, f64)> {
    let s = xyz.x + xyz.y + xyz.z;
    if !(s > 0.0) || !s.is_finite() {
        return None;
    }
    Some((xyz.x / s, xyz.y / s))
}

/// XYZ (D65 white) to linear sRGB, the matrix of the flame paper's eq (17) (the
/// IEC 61966-2-1 / ITU-R BT.709 primaries).
pub fn xyz_to_linear_srgb(xyz: DVec3) -> DVec3 {
    DVec3::new(
        3.240479 * xyz.x - 1.537150 * xyz.y - 0.498535 * xyz.z,
        -0.969256 * xyz.x + 1.875992 * xyz.y + 0.041556 * xyz.z,
        0.055648 * xyz.x - 0.204043 * xyz.y + 1.057311 * xyz.z,
    )
}

/// Linear sRGB to XYZ (D65 white); the inverse of [`xyz_to_linear_srgb`] to the six
/// digits both matrices are printed with.
pub fn linear_srgb_to_xyz(rgb: DVec3) -> DVec3 {
    DVec3::new(
        0.412453 * rgb.x + 0.357580 * rgb.y + 0.180423 * rgb.z,
        0.212671 * rgb.x + 0.715160 * rgb.y + 0.072169 * rgb.z,
        0.019334 * rgb.x + 0.119193 * rgb.y + 0.950227 * rgb.z,
    )
}

/// The blackbody's colour as a display-ready chromaticity: linear sRGB from eq (17),
/// negative components clipped to 0, scaled so that the largest component is 1.
///
/// This is the paper's Fig 1 texture and the `export blackbody` table. Black (all zero)
/// when the body has no visible emission.
pub fn blackbody_srgb_normalized(temperature_k: f64) -> DVec3 {
    let rgb = xyz_to_linear_srgb(blackbody_xyz(Observer::Cie1931TwoDegree, temperature_k)).max(DVec3::ZERO);
    let m = rgb.max_element();
    if m > 0.0 && m.is_finite() { rgb / m } else { DVec3::ZERO }
}

/// The sRGB transfer function (IEC 61966-2-1): linear [0, 1] to encoded [0, 1].
/// Input is clamped to [0, 1]; NaN encodes as 0.
pub fn srgb_encode(linear: f32) -> f32 {
    let v = if linear.is_nan() { 0.0 } else { linear.clamp(0.0, 1.0) };
    if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// Inverse of [`srgb_encode`]: encoded [0, 1] to linear [0, 1].
pub fn srgb_decode(encoded: f32) -> f32 {
    let v = if encoded.is_nan() { 0.0 } else { encoded.clamp(0.0, 1.0) };
    if v <= 0.040_45 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

/// Encode a linear value to an 8-bit sRGB code (rounded to nearest).
pub fn srgb_encode_u8(linear: f32) -> u8 {
    (srgb_encode(linear) * 255.0 + 0.5) as u8
}

/// The same result as [`srgb_encode_u8`] for every input, without a `powf` per sample:
/// the 255 linear thresholds where the code steps up, and per bucket of 2¹⁵ consecutive
/// f32 bit patterns the code at the bucket's start; a bucket spans at most one
/// threshold in practice (its relative width 2⁻⁸ is below the codes' spacing), and the
/// loop steps over any it holds. About 20 times faster than the direct encoder for whole
/// frames.
pub fn srgb_encode_u8_fast(linear: f32) -> u8 {
    const SHIFT: u32 = 15;
    struct Tables {
        /// The 255 thresholds, then +∞ (so that code 255 never steps).
        thresholds: [f32; 256],
        start: Vec<u8>,
    }
    static TABLES: std::sync::OnceLock<Tables> = std::sync::OnceLock::new();
    let t = TABLES.get_or_init(|| {
        // thresholds[k - 1] is the smallest non-negative f32 whose code is >= k, found by
        // bisection over the bit patterns (the encoder is monotone in its input).
        let thresholds: [f32; 256] = std::array::from_fn(|k| {
            if k == 255 {
                return f32::INFINITY;
            }
            let code = (k + 1) as u8;
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if srgb_encode_u8(f32::from_bits(mid)) >= code { hi = mid } else { lo = mid + 1 }
            }
            f32::from_bits(lo)
        });
        let start = (0..=(1.0f32.to_bits() >> SHIFT))
            .map(|i| thresholds.partition_point(|&th| th <= f32::from_bits(i << SHIFT)) as u8)
            .collect();
        Tables { thresholds, start }
    });
    if !(linear > 0.0) {
        return 0; // NaN, negative, zero
    }
    if linear >= 1.0 {
        return 255;
    }
    let mut code = t.start[(linear.to_bits() >> SHIFT) as usize];
    // One step without a branch (a bucket holds at most one threshold); the loop is
    // for safety and is never taken.
    code += u8::from(t.thresholds[code as usize] <= linear);
    while t.thresholds[code as usize] <= linear {
        code += 1;
    }
    code
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_cover_the_documented_ranges() {
        assert_eq!(Observer::Cie1931TwoDegree.range_nm(), (360, 830));
        let (lo, hi) = Observer::Cie2015TwoDegree.range_nm();
        assert!(lo <= 391 && hi == 830, "CIE 2015 range {lo}-{hi}");
    }

    #[test]
    fn cie1931_peak_values_match_the_standard() {
        // CIE 015:2018 Table: ȳ(555) = 1.0 (to 4 decimals: 1.0000), x̄(600) = 1.0622.
        let c = Observer::Cie1931TwoDegree.cmf(555.0);
        assert!((c.y - 1.0).abs() < 1e-4, "{c:?}");
        let c = Observer::Cie1931TwoDegree.cmf(600.0);
        assert!((c.x - 1.0622).abs() < 1e-4, "{c:?}");
    }

    #[test]
    fn interpolation_is_linear_between_samples() {
        let o = Observer::Cie1931TwoDegree;
        let mid = o.cmf(557.5);
        let expect = (o.cmf(557.0) + o.cmf(558.0)) * 0.5;
        assert!((mid - expect).abs().max_element() < 1e-12);
        assert_eq!(o.cmf(300.0), DVec3::ZERO);
        assert_eq!(o.cmf(f64::NAN), DVec3::ZERO);
    }

    #[test]
    fn planck_matches_wien_peak() {
        // Wien's displacement law: λ_max = b / T with b = 2.897771955e-3 m·K.
        let t = 5000.0;
        let peak = (300..1200)
            .map(|nm| (nm, planck_exitance(nm as f64, t)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|p| p.0)
            .unwrap_or(0);
        let wien_nm = 2.897_771_955e-3 / t * 1e9;
        assert!((peak as f64 - wien_nm).abs() <= 1.0, "{peak} vs {wien_nm}");
    }

    #[test]
    fn blackbody_is_finite_from_1k_to_40000k() {
        let mut t = 1.0;
        while t <= 40_000.0 {
            let xyz = blackbody_xyz(Observer::Cie1931TwoDegree, t);
            assert!(xyz.is_finite(), "T = {t}: {xyz:?}");
            let rgb = blackbody_srgb_normalized(t);
            assert!(rgb.is_finite(), "T = {t}: {rgb:?}");
            assert!(rgb.max_element() == 0.0 || (rgb.max_element() - 1.0).abs() < 1e-12);
            t *= 1.01;
        }
        assert_eq!(blackbody_srgb_normalized(1.0), DVec3::ZERO);
        assert_eq!(blackbody_srgb_normalized(f64::NAN), DVec3::ZERO);
    }

    #[test]
    fn d65_like_blackbody_is_near_white() {
        // A 6504 K blackbody lies close to D65 (x = 0.3127, y = 0.3290): the Planckian
        // locus passes within 0.004 of it in xy.
        let (x, y) = xy_chromaticity(blackbody_xyz(Observer::Cie1931TwoDegree, 6504.0)).unwrap_or((0.0, 0.0));
        assert!((x - 0.3127).abs() < 0.004 && (y - 0.3290).abs() < 0.006, "{x} {y}");
    }

    #[test]
    fn srgb_transfer_round_trips() {
        for i in 0..=1000 {
            let v = i as f32 / 1000.0;
            assert!((srgb_decode(srgb_encode(v)) - v).abs() < 1e-5);
        }
        assert_eq!(srgb_encode_u8(1.0), 255);
        assert_eq!(srgb_encode_u8(0.0), 0);
        assert_eq!(srgb_encode_u8(f32::NAN), 0);
    }

    #[test]
    fn fast_encoder_equals_the_direct_one() {
        // Every f32 in [0, 1] with the low 8 mantissa bits varied coarsely, plus the
        // neighbours of each threshold: the two encoders agree exactly.
        let mut bits = 0u32;
        while bits <= 1.0f32.to_bits() {
            let v = f32::from_bits(bits);
            assert_eq!(srgb_encode_u8_fast(v), srgb_encode_u8(v), "{v:e}");
            bits += 97;
        }
        for k in 1..=255u8 {
            let mut x = 0.0f32;
            while srgb_encode_u8(x) < k {
                x = (x + 1e-3).min(1.0);
            }
            for b in x.to_bits().saturating_sub(40_000)..x.to_bits() + 40_000 {
                let v = f32::from_bits(b);
                assert_eq!(srgb_encode_u8_fast(v), srgb_encode_u8(v), "{v:e}");
            }
        }
        for v in [-1.0, 2.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN] {
            assert_eq!(srgb_encode_u8_fast(v), srgb_encode_u8(v));
        }
    }

    #[test]
    fn matrices_are_inverse() {
        let v = DVec3::new(0.3, 0.5, 0.2);
        let back = xyz_to_linear_srgb(linear_srgb_to_xyz(v));
        assert!((back - v).abs().max_element() < 1e-5);
    }
}
