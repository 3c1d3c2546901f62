//! Auroral emission lines and what share of the excited states radiates before a
//! collision takes its energy (quenching), in two models:
//!
//! - the thesis's (`paper` mode, §2.4.2): an excited particle is de-excited with the
//!   hard-sphere collision probability P_v = 1 - exp(-√2 n π r² v_a τ) (eq 2.25) with the
//!   mean thermal speed v_a = √(8 k_B T / (π m_a)) (eq 2.26);
//! - the `physical` mode's: the fraction A_line / (1/τ + Σ k_i n_i) with measured rate
//!   coefficients k_i (NCAR GLOW, `gchem.f90`, as tabulated in shared/aurora-physics.md).
//!
//! With real densities the first quenches the green line almost completely at 110 km,
//! where real aurora is brightest; the second leaves most of it (tested below).
//!
//! ```
//! use phenomena_aurora::atmosphere::Atmosphere;
//! use phenomena_aurora::emission::Line;
//! let at_110 = Atmosphere::msis21().at(110.0);
//! assert!(Line::O557.radiated_fraction(&at_110) > 0.8);
//! assert!(Line::O630.radiated_fraction(&at_110) < 1e-3); // red is quenched down here
//! ```

use crate::atmosphere::Sample;

/// Boltzmann constant, J/K (exact, SI 2019).
pub const BOLTZMANN_J_K: f64 = 1.380_649e-23;
/// m³ per cm³: rate coefficients are tabulated in cm³ s⁻¹, densities kept in m⁻³.
const M3_PER_CM3: f64 = 1e-6;

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

    /// Collisional de-excitation rate Σ k_i n_i of the upper state, s⁻¹ (GLOW's rate
    /// coefficients; 0 for the prompt bands).
    pub fn quenching_rate_s(self, air: &Sample) -> f64 {
        let t = air.temperature_k;
        let (n_o, n_n2, n_o2) = (air.n_o_m3 * M3_PER_CM3, air.n_n2_m3 * M3_PER_CM3, air.n_o2_m3 * M3_PER_CM3);
        match self {
            // O(¹S) + O: 2.0e-14; O(¹S) + O2: 4.0e-12 exp(-865/T).
            Line::O557 => 2.0e-14 * n_o + 4.0e-12 * (-865.0 / t).exp() * n_o2,
            // O(¹D) + N2: 2.0e-11 exp(107.8/T); + O2: 2.9e-11 exp(67.5/T); + O: 3.0e-12.
            Line::O630 => {
                2.0e-11 * (107.8 / t).exp() * n_n2 + 2.9e-11 * (67.5 / t).exp() * n_o2 + 3.0e-12 * n_o
            }
            _ => 0.0,
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

/// Mean thermal speed of a gas particle of mass `mass_kg` at `temperature_k`, m/s:
/// v_a = √(8 k_B T / (π m_a)) (thesis eq 2.26).
pub fn mean_speed_m_s(temperature_k: f64, mass_kg: f64) -> f64 {
    (8.0 * BOLTZMANN_J_K * temperature_k / (std::f64::consts::PI * mass_kg)).sqrt()
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
        let v = mean_speed_m_s(s.temperature_k, 28.014 * 1.660_539_066_60e-27);
        assert!((400.0..450.0).contains(&v), "mean N2 speed at {} K: {v}", s.temperature_k);
        let p = paper_quenching_probability(n, 1.8e-10, v, Line::O557.lifetime_s());
        assert!(p > 0.999, "P_v = {p}");
        assert!(Line::O557.radiated_fraction(&s) > 0.85);
        // And it vanishes in vacuum.
        assert_eq!(paper_quenching_probability(0.0, 1.8e-10, v, 0.905), 0.0);
    }
}
