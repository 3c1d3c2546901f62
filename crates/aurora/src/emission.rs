//! Auroral emission lines and what share of the excited states radiates before a
//! collision takes its energy (quenching), in two models:
//!
//! - the thesis's (`paper` mode, §2.4.2): an excited particle is de-excited with the
//!   collision probability P_v = 1 - exp(-√2 n π r² v_a τ) (eq 2.25) with the mean
//!   thermal speed v_a = √(8 k_B T / (π m_a)) (eq 2.26), here with the fall's hard-sphere
//!   radius and a fixed τ ([`paper_quenching_probability`]; `quenching = "hard-sphere"`);
//!   the `paper` default makes eq 2.25 exact for the measured coefficients below
//!   ([`crate::fall::PaperQuenching::Measured`]);
//! - the `physical` mode's: the fraction A_line / (1/τ + Σ k_i n_i) with measured rate
//!   coefficients k_i (NCAR GLOW, `gchem.f90`, as tabulated in shared/aurora-physics.md,
//!   with the sources GLOW cites; O(¹D) + O temperature-dependent after Sun and Dalgarno
//!   1992, and O(¹D) + e, see [`Line::electron_quenching_rate_s`]).
//!
//! With real densities the hard-sphere form quenches the green line almost completely at
//! 110 km, where real aurora is brightest; the measured coefficients leave most of it
//! (tested below).
//!
//! The colour of each line: Table 2.1's x̄ȳz̄ as printed (`paper`) or the CIE 2015 2°
//! observer of the core (the same values to Table 2.1's four digits), and XYZ -> RGB by
//! the matrix of eq (2.30).
//!
//! ```
//! use phenomena_aurora::atmosphere::Atmosphere;
//! use phenomena_aurora::emission::Line;
//! let at_110 = Atmosphere::msis21().at(110.0);
//! assert!(Line::O557.radiated_fraction(&at_110) > 0.8);
//! assert!(Line::O630.radiated_fraction(&at_110) < 1e-3); // red is quenched down here
//! ```

use glam::DVec3;
use phenomena_core::color::{BOLTZMANN_J_PER_K, Observer, spectral_line_xyz};

use crate::atmosphere::Sample;

/// m³ per cm³: rate coefficients are tabulated in cm³ s⁻¹, densities kept in m⁻³.
pub(crate) const M3_PER_CM3: f64 = 1e-6;

/// The five lines of the thesis (§2.4.2, Table 2.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Line {
    /// N2⁺ first negative band, 391.4 nm (prompt).
    N2p391,
    /// N2⁺ first negative band, 427.8 nm (prompt).
    N2p428,
    /// O(¹S) -> O(¹D), 557.7 nm, the green line.
    O557,
    /// O(¹D) -> O(³P), 630.0 nm, the red line.
    O630,
    /// N2 first positive band, 670.5 nm (prompt).
    N2_670,
}

impl Line {
    /// All five, in the order of Table 2.1's wavelengths sorted ascending.
    pub const ALL: [Line; 5] = [Line::N2p391, Line::N2p428, Line::O557, Line::O630, Line::N2_670];

    /// Position in [`Line::ALL`].
    pub fn index(self) -> usize {
        match self {
            Line::N2p391 => 0,
            Line::N2p428 => 1,
            Line::O557 => 2,
            Line::O630 => 3,
            Line::N2_670 => 4,
        }
    }

    /// Wavelength, nm.
    pub fn wavelength_nm(self) -> f64 {
        match self {
            Line::N2p391 => 391.4,
            Line::N2p428 => 427.8,
            Line::O557 => 557.7,
            Line::O630 => 630.0,
            Line::N2_670 => 670.5,
        }
    }

    /// Colour-matching values (x̄, ȳ, z̄) as printed in the thesis's Table 2.1 (the `paper`
    /// mode's colour map, §2.4.3).
    pub fn table_2_1_cmf(self) -> DVec3 {
        match self {
            Line::O557 => DVec3::new(0.5739, 0.9993, 0.0018),
            Line::O630 => DVec3::new(0.6924, 0.2981, 0.0000),
            Line::N2p391 => DVec3::new(0.0049, 0.0005, 0.0239),
            Line::N2p428 => DVec3::new(0.2736, 0.0299, 1.4463),
            Line::N2_670 => DVec3::new(0.0893, 0.0345, 0.0000),
        }
    }

    /// Colour-matching values (x̄, ȳ, z̄) from the CIE 2015 2° observer tabulated in the
    /// core (linear between its 1 nm samples): what Table 2.1 lists, to its 4 digits.
    pub fn cie2015_cmf(self) -> DVec3 {
        spectral_line_xyz(Observer::Cie2015TwoDegree, self.wavelength_nm(), 1.0)
    }

    /// Einstein coefficient of the line and total radiative rate of its upper state
    /// (1/τ), s⁻¹, for the metastable oxygen lines (GLOW: O(¹S) 557.7 nm A = 1.06 plus
    /// 297.2 nm A = 0.045, τ = 0.905 s; O(¹D) 630.0 nm A = 0.00585 plus 636.4 nm
    /// A = 0.00185, τ = 130 s). `None` for the prompt N2 and N2⁺ bands.
    pub fn metastable_rates(self) -> Option<(f64, f64)> {
        match self {
            Line::O557 => Some((1.06, 1.06 + 0.045)),
            Line::O630 => Some((0.00585, 0.00585 + 0.00185)),
            _ => None,
        }
    }

    /// Lifetime τ of the upper state, s (0 for the prompt bands).
    pub fn lifetime_s(self) -> f64 {
        self.metastable_rates().map_or(0.0, |(_, total)| 1.0 / total)
    }

    /// Collisional de-excitation rate Σ k_i n_i of the upper state by the neutrals, s⁻¹
    /// (0 for the prompt bands):
    /// - O(¹S) + O: 2.0e-14 cm³ s⁻¹ (Slanger and Black 1981); O(¹S) + O₂:
    ///   4.0e-12 exp(-865/T) (Slanger et al. 1972) (GLOW's k11, k36);
    /// - O(¹D) + N₂: 2.0e-11 exp(107.8/T); O(¹D) + O₂: 2.9e-11 exp(67.5/T) (Streit et al.
    ///   1976, J. Chem. Phys. 65, 4761, as GLOW's k8, k9 and shared/aurora-physics.md
    ///   have them; the JPL evaluation's 2.15e-11 exp(110/T) and 3.3e-11 exp(55/T) are
    ///   within 9 % and 13 % of these over 200-1100 K);
    /// - O(¹D) + O: (3.73 + 0.11965 √T - 6.5898e-4 T) × 1e-12 (Sun and Dalgarno 1992, J.
    ///   Chem. Phys. 96, 5017, quantum scattering on the O₂ potential curves; 5.6e-12 at
    ///   300 K, 6.9e-12 at 1000 K), in place of GLOW's constant 3.0e-12 (Abreu et al.
    ///   1986), which the issue's "temperature-dependent" asks to replace.
    pub fn quenching_rate_s(self, air: &Sample) -> f64 {
        let t = air.temperature_k;
        let (n_o, n_n2, n_o2) = (air.n_o_m3 * M3_PER_CM3, air.n_n2_m3 * M3_PER_CM3, air.n_o2_m3 * M3_PER_CM3);
        match self {
            Line::O557 => 2.0e-14 * n_o + 4.0e-12 * (-865.0 / t).exp() * n_o2,
            Line::O630 => {
                2.0e-11 * (107.8 / t).exp() * n_n2
                    + 2.9e-11 * (67.5 / t).exp() * n_o2
                    + o1d_o_rate_cm3_s(t) * n_o
            }
            _ => 0.0,
        }
    }

    /// Collisional de-excitation rate of the upper state by thermal electrons of
    /// `electron_density_cm3` at `electron_temperature_k`, s⁻¹: O(¹D) + e,
    /// 8.1e-10 (Tₑ/300)^0.5 cm³ s⁻¹ (Link 1982, GLOW's k10); negligible for O(¹S) and 0
    /// for the prompt bands.
    pub fn electron_quenching_rate_s(self, electron_density_cm3: f64, electron_temperature_k: f64) -> f64 {
        match self {
            Line::O630 => 8.1e-10 * (electron_temperature_k / 300.0).sqrt() * electron_density_cm3,
            _ => 0.0,
        }
    }

    /// [`Line::radiated_fraction`] with the thermal electrons' quenching too:
    /// A_line / (1/τ + Σ k_i n_i + k_e nₑ).
    pub fn radiated_fraction_with_electrons(
        self,
        air: &Sample,
        electron_density_cm3: f64,
        electron_temperature_k: f64,
    ) -> f64 {
        match self.metastable_rates() {
            Some((a_line, total)) => {
                a_line
                    / (total
                        + self.quenching_rate_s(air)
                        + self.electron_quenching_rate_s(electron_density_cm3, electron_temperature_k))
            }
            None => 1.0,
        }
    }

    /// Share of the upper states made that emit this line: A_line / (1/τ + Σ k_i n_i)
    /// for the oxygen lines, 1 for the prompt bands (whose branching is counted where
    /// the states are made).
    pub fn radiated_fraction(self, air: &Sample) -> f64 {
        match self.metastable_rates() {
            Some((a_line, total)) => a_line / (total + self.quenching_rate_s(air)),
            None => 1.0,
        }
    }
}

/// O(¹D) + O → O(³P) + O, cm³ s⁻¹ at `temperature_k`: Sun and Dalgarno (1992)'s fit
/// (3.73 + 0.11965 √T - 6.5898e-4 T) × 1e-12.
pub fn o1d_o_rate_cm3_s(temperature_k: f64) -> f64 {
    let t = temperature_k;
    (3.73 + 0.11965 * t.sqrt() - 6.5898e-4 * t) * 1e-12
}

/// XYZ to RGB by the matrix of the thesis's eq (2.30) as printed (the sRGB / BT.709
/// primaries with a D65 white, to six digits).
pub fn xyz_to_rgb_eq_2_30(xyz: DVec3) -> DVec3 {
    DVec3::new(
        3.24097 * xyz.x - 1.53738 * xyz.y - 0.498612 * xyz.z,
        -0.969241 * xyz.x + 1.87596 * xyz.y + 0.0415554 * xyz.z,
        0.0556299 * xyz.x - 0.203976 * xyz.y + 1.05697 * xyz.z,
    )
}

/// Mean thermal speed of a gas particle of mass `mass_kg` at `temperature_k`, m/s:
/// v_a = √(8 k_B T / (π m_a)) (thesis eq 2.26).
pub fn mean_speed_m_s(temperature_k: f64, mass_kg: f64) -> f64 {
    (8.0 * BOLTZMANN_J_PER_K * temperature_k / (std::f64::consts::PI * mass_kg)).sqrt()
}

/// The thesis's probability that an excited particle is de-excited by a collision before
/// it radiates, P_v = 1 - exp(-√2 n π r² v_a τ) (eq 2.25), for number density
/// `n_m3`, particle radius `radius_m`, mean speed `speed_m_s` and lifetime `lifetime_s`.
pub fn paper_quenching_probability(n_m3: f64, radius_m: f64, speed_m_s: f64, lifetime_s: f64) -> f64 {
    let rate = std::f64::consts::SQRT_2 * n_m3 * std::f64::consts::PI * radius_m * radius_m * speed_m_s;
    -(-rate * lifetime_s).exp_m1()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::Atmosphere;

    #[test]
    fn table_2_1_is_the_cie_2015_observer() {
        // Table 2.1 prints 4 decimals; linear interpolation between the 1 nm samples
        // differs from the printed values by at most one unit in the last digit here
        // (measured: 1e-4 at 557.7 ȳ, 391.4 z̄, 427.8 z̄, 630.0 x̄, 670.5 x̄).
        for line in Line::ALL {
            let (printed, ours) = (line.table_2_1_cmf(), line.cie2015_cmf());
            assert!((printed - ours).abs().max_element() <= 1.5e-4, "{line:?}: {printed} vs {ours}");
        }
    }

    #[test]
    fn eq_2_30_is_the_srgb_matrix() {
        // The core's sRGB matrix (flame paper eq 17, the older IEC 61966-2-1 digits) and
        // eq (2.30) (derived from the exact D65 chromaticity) are two published roundings
        // of one matrix; their elements differ by at most 4.9e-4 (3.24097 vs 3.240479).
        for xyz in [DVec3::X, DVec3::Y, DVec3::Z] {
            let (a, b) = (xyz_to_rgb_eq_2_30(xyz), phenomena_core::color::xyz_to_linear_srgb(xyz));
            assert!((a - b).abs().max_element() <= 5e-4, "{xyz}: {a} vs {b}");
        }
        // D65 white (x, y = 0.3127, 0.3290) maps to equal R, G, B.
        let w = xyz_to_rgb_eq_2_30(DVec3::new(0.3127 / 0.3290, 1.0, (1.0 - 0.3127 - 0.3290) / 0.3290));
        assert!((w.x - w.y).abs() < 1e-3 && (w.y - w.z).abs() < 1e-3, "{w}");
    }

    #[test]
    fn lifetimes_are_the_tabulated_ones() {
        // shared/aurora-physics.md: τ(¹S) = 0.905 s, τ(¹D) = 130 s (to the digits given).
        assert!((Line::O557.lifetime_s() - 0.905).abs() < 0.001);
        assert!((Line::O630.lifetime_s() - 130.0).abs() < 0.5);
        assert_eq!(Line::N2p391.lifetime_s(), 0.0);
    }

    #[test]
    fn the_green_line_survives_at_110_km_and_the_red_one_only_high_up() {
        let air = Atmosphere::msis21();
        // At 110 km: O(¹S) quenching (~0.03 s⁻¹) is small next to 1/τ = 1.1 s⁻¹, so about
        // 1.06/1.14 = 93 % radiates; O(¹D) meets N2 at ~44 s⁻¹ against 1/τ = 0.0077 s⁻¹.
        let low = air.at(110.0);
        let green = Line::O557.radiated_fraction(&low);
        assert!((0.85..0.96).contains(&green), "557.7 nm at 110 km: {green}");
        assert!(Line::O630.radiated_fraction(&low) < 1e-3);
        // At 300 km quenching of O(¹D) is comparable to its radiative rate.
        let red_high = Line::O630.radiated_fraction(&air.at(300.0));
        assert!((0.3..0.76).contains(&red_high), "630.0 nm at 300 km: {red_high}");
        // Electrons: 1e5 cm⁻³ at 1000 K quench at 1.5e-4 s⁻¹, 2 % of 1/τ.
        let e = Line::O630.electron_quenching_rate_s(1e5, 1000.0);
        assert!((1.4e-4..1.6e-4).contains(&e), "{e}");
        assert_eq!(Line::N2p428.electron_quenching_rate_s(1e5, 1000.0), 0.0);
        // Sun and Dalgarno's O(¹D) + O at its published anchors (5.6e-12 at 300 K).
        assert!((o1d_o_rate_cm3_s(300.0) / 5.6e-12 - 1.0).abs() < 0.01);
        // The red line's share grows with altitude through the thermosphere.
        let mut last = 0.0;
        for z in (120..=500).step_by(20) {
            let f = Line::O630.radiated_fraction(&air.at(f64::from(z)));
            assert!(f > last, "630.0 nm share at {z} km: {f} after {last}");
            last = f;
        }
        // Never more than the line's branching ratio A_line·τ.
        assert!(last < 0.00585 / 0.0077 + 1e-12);
    }

    #[test]
    fn the_papers_hard_sphere_quenching_kills_the_green_line_at_110_km() {
        // Eq (2.25)-(2.26) with real densities: N2-sized spheres (kinetic radius
        // 1.8e-10 m), mean speed of N2 at the local temperature, τ(¹S) = 0.905 s.
        let s = Atmosphere::msis21().at(110.0);
        let n = s.n_o_m3 + s.n_n2_m3 + s.n_o2_m3;
        let v = mean_speed_m_s(s.temperature_k, crate::atmosphere::MASS_N2 * crate::atmosphere::DALTON_KG);
        assert!((400.0..450.0).contains(&v), "mean N2 speed at {} K: {v}", s.temperature_k);
        let p = paper_quenching_probability(n, 1.8e-10, v, Line::O557.lifetime_s());
        assert!(p > 0.999, "P_v = {p}");
        assert!(Line::O557.radiated_fraction(&s) > 0.85);
        // And it vanishes in vacuum.
        assert_eq!(paper_quenching_probability(0.0, 1.8e-10, v, 0.905), 0.0);
    }
}
