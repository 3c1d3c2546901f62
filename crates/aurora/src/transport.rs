//! Transport of the low-energy electrons along the field line: the two-stream
//! equations of Banks and Nagy (1970, J. Geophys. Res. 75, 6260) for the electrons below
//! [`TRANSPORT_TOP_EV`], so that the 4-10 eV electrons that make most O(¹D) excite it
//! where they go, not where they are born.
//!
//! Why: [`crate::degradation`]'s local balance assumes an electron loses its energy where
//! it was made. Near 200 km and above, a 5 eV electron needs 50-500 km of path to lose
//! it and scatters elastically every few km, so it diffuses tens of km: up, into thinner
//! air that cannot stop it (where it escapes), and down, into denser air that does. The
//! local balance puts all its O(¹D) at its birth altitude, which makes the O(¹D) yield
//! per ion pair rise with altitude; transport makes it fall above the layer where the
//! electrons are stopped (GLOW, Solomon et al. 1988, shows the same).
//!
//! The equations, for the up- and down-going hemispherical fluxes φ± of one energy bin
//! (cm⁻² s⁻¹, so that the collision rate is n σ (φ⁺ + φ⁻)), along a vertical field line:
//!
//! ```text
//!  μ̄ dφ⁺/dz = -(A + B) φ⁺ + B φ⁻ + S/2
//! -μ̄ dφ⁻/dz = -(A + B) φ⁻ + B φ⁺ + S/2
//! ```
//!
//! with A = Σ nσ of every collision that moves the electron out of the bin (the same
//! inelastic, ionising and thermal-electron losses as the local balance), B = Σ nσ_b the
//! elastic backscatter, S the electrons arriving in the bin (cm⁻³ s⁻¹), and μ̄ = 1/2
//! (isotropic hemispheres). Their sum u = φ⁺ + φ⁻ obeys exactly
//! `-μ̄² d/dz (1/(A + 2B) du/dz) + A u = S`, solved here by finite volumes on the
//! atmosphere's altitudes (a tridiagonal system per bin; where the air is thick it
//! reduces to the local balance u = S/A). Boundaries: nothing comes down from above the
//! top (φ⁻ = 0, so μ̄ u escapes) nor up from below the bottom (φ⁺ = 0). Bins are solved
//! from the top down; the collisions of each go, at the same altitude, into the bins
//! below, as in the local balance.
//!
//! Choices, each a simplification stated:
//! - **Where transport starts.** Above [`TRANSPORT_TOP_EV`] the electrons are handled
//!   locally, as before: the primaries' transport is in Fang et al.'s (2010) ionisation
//!   profile, and the degraded primaries and secondaries that the local balance puts
//!   below [`TRANSPORT_TOP_EV`] (per ion pair of that profile) are this solver's source.
//!   Most secondaries are born below ~50 eV (Green and Sawada's spectrum); the result
//!   moves by under 1 km of the 630.0 nm peak between 50 and 200 eV (test
//!   `the_transport_top_barely_matters`).
//! - **Backscatter** from the momentum-transfer cross section σₘ: σ_b = σₘ / 2 (the
//!   transport approximation, which gives the two-stream the diffusion coefficient of
//!   the true angular distribution; for isotropic scattering σₘ = σ_el and half the
//!   collisions reverse the hemisphere). Values in `MOMENTUM_TRANSFER`.
//! - **Isotropic sources**: every electron arriving in a bin, secondary or degraded, is
//!   split evenly between the hemispheres (degraded primaries keep some of their
//!   direction in reality).
//! - **Vertical field line** (GLOW gives a dip of 75° at 65° N 0° E, 77° over Tromsø:
//!   sin I = 0.97).
//!
//! The ionisation stays Fang et al.'s: the transported electrons' own ionisations (a
//! small share, from the 14-100 eV bins) are counted but do not replace it.

use crate::degradation::{Degradation, LocalAir, Tally};

/// Electrons below this energy, eV, are transported; above it the local balance holds.
pub const TRANSPORT_TOP_EV: f64 = 100.0;

/// Hemispherical mean cosine of the two-stream approximation (isotropic hemispheres).
const MU: f64 = 0.5;

/// Elastic momentum-transfer cross sections σₘ of O, O₂, N₂, 1e-16 cm², at
/// [`MT_ENERGY_EV`] (tabulated points of recommended data; O's at 50 and 70 eV are
/// interpolated log-log in its table):
/// - O: Laher and Gilmore (1990, J. Phys. Chem. Ref. Data 19, 277), as the LXCat ELASTIC
///   set of IST-Lisbon's LoKI (`Code/Input/Oxygen/O_LXCat.txt`); above 40 eV that file
///   continues with a smooth fit, less certain;
/// - O₂: Song et al. (2026, J. Phys. Chem. Ref. Data 55, 013102, Table V), the successor
///   of Itikawa (2009); ~20 % uncertain at 1-10 eV;
/// - N₂: Elford, Buckman and Brunger (2003, Landolt-Börnstein I/17C, Table 6.3.5.3), the
///   values Itikawa (2006, J. Phys. Chem. Ref. Data 35, 31) adopted; the 2-3 eV shape
///   resonance is only sampled at 2 and 3 eV here (it peaks at ~24 near 2.2 eV).
const MOMENTUM_TRANSFER: [[f64; 13]; 3] = [
    [2.80, 3.55, 4.01, 4.41, 4.60, 4.84, 5.03, 4.99, 4.65, 4.18, 3.56, 3.18, 2.61],
    [6.70, 6.50, 6.10, 6.00, 5.70, 6.22, 6.72, 6.89, 7.01, 6.00, 3.50, 2.50, 1.50],
    [11.07, 13.65, 14.28, 10.9, 9.9, 9.29, 9.45, 9.97, 8.2, 6.8, 5.6, 3.59, 2.19],
];

/// Energies of [`MOMENTUM_TRANSFER`], eV.
const MT_ENERGY_EV: [f64; 13] = [1.0, 2.0, 3.0, 4.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 50.0, 70.0, 100.0];

/// σₘ of species `s` at `e_ev`, cm²: log-log between the table's energies, constant
/// outside it.
pub fn momentum_transfer_cm2(s: usize, e_ev: f64) -> f64 {
    let t = &MOMENTUM_TRANSFER[s];
    let x = &MT_ENERGY_EV;
    let v = if e_ev <= x[0] {
        t[0]
    } else if e_ev >= x[x.len() - 1] {
        t[t.len() - 1]
    } else {
        let k = x.partition_point(|&c| c <= e_ev) - 1;
        let f = (e_ev / x[k]).ln() / (x[k + 1] / x[k]).ln();
        (t[k].ln() + f * (t[k + 1] / t[k]).ln()).exp()
    };
    v * 1e-16
}

/// The air at one altitude of the column, for the transport.
#[derive(Clone, Copy, Debug)]
pub struct TransportAir {
    /// Altitude, cm.
    pub altitude_cm: f64,
    /// O, O₂, N₂, cm⁻³.
    pub densities_cm3: [f64; 3],
    /// Thermal electrons, cm⁻³.
    pub electron_density_cm3: f64,
    /// Electron temperature, K.
    pub electron_temperature_k: f64,
    /// Ionisation rate of the precipitation (Fang et al. 2010), cm⁻³ s⁻¹.
    pub ionisation_cm3_s: f64,
}

/// What the electrons make at one altitude, cm⁻³ s⁻¹.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImpactRates {
    /// O(¹D) by electron impact on O.
    pub o1d: f64,
    /// O₂ dissociations through the Schumann-Runge continuum (each gives one O(¹D)).
    pub o2_dissociation: f64,
    /// N₂ dissociations through its predissociating states.
    pub n2_dissociation: f64,
    /// Ionisations, O + O₂ + N₂ (the counted ones: local above the transport, transported
    /// below).
    pub ionisation: f64,
}

/// The rates of electron impact at every altitude of `column` (bottom up, strictly
/// increasing altitudes), with the electrons below [`TRANSPORT_TOP_EV`] transported.
/// `local_only` solves the same bins without the transport term (each altitude alone),
/// which is the local balance of [`Degradation::yields`] times the ionisation: the test
/// of the solver's limit.
pub fn impact_rates(column: &[TransportAir], local_only: bool) -> Vec<ImpactRates> {
    impact_rates_from(column, local_only, TRANSPORT_TOP_EV)
}

/// [`impact_rates`] with the transport starting at `top_ev`.
fn impact_rates_from(column: &[TransportAir], local_only: bool, top_ev: f64) -> Vec<ImpactRates> {
    let deg = Degradation::shared();
    let e = deg.energies_ev();
    let top = e.partition_point(|&c| c <= crate::degradation::INJECTION_EV).clamp(21, e.len()) - 1;
    let jc = deg.bin_at_or_above(top_ev).min(top);
    let airs: Vec<LocalAir> = column
        .iter()
        .map(|c| LocalAir::new(c.densities_cm3, c.electron_density_cm3, c.electron_temperature_k))
        .collect();
    let (mut source, mut tally) = local_balance(deg, column, &airs, top, jc);
    transport_bins(deg, column, &airs, jc, local_only, &mut source, &mut tally);
    tally
        .iter()
        .map(|t| ImpactRates {
            o1d: t.o1d,
            o2_dissociation: t.o2_dissociation,
            n2_dissociation: t.n2_dissociation,
            ionisation: t.ions.iter().sum(),
        })
        .collect()
}

/// The local balance of the bins above `jc` at every altitude, per injected electron
/// (in bin `top`), scaled to the altitude's ionisation: the source of the transported
/// bins (rows of `jc`, one per altitude) and the tallies of the bins above them.
fn local_balance(
    deg: &Degradation,
    column: &[TransportAir],
    airs: &[LocalAir],
    top: usize,
    jc: usize,
) -> (Vec<f64>, Vec<Tally>) {
    let n = column.len();
    let mut source = vec![0.0; n * jc];
    let mut tally = vec![Tally::default(); n];
    for (i, (c, air)) in column.iter().zip(airs).enumerate() {
        let mut inflow = vec![0.0; top + 1];
        inflow[top] = 1.0;
        let mut high = Tally::default();
        let mut snapshot = Vec::new();
        let mut all = Tally::default();
        for j in (0..=top).rev() {
            if j + 1 == jc {
                snapshot = inflow[..jc].to_vec();
                high = all;
            }
            let (out, thermal) = deg.removal_cm(j, air);
            if out > 0.0 {
                deg.collide(j, air, inflow[j] / out, thermal, &mut inflow, &mut all);
            }
        }
        let ions: f64 = all.ions.iter().sum();
        if !(ions > 0.0) || !(c.ionisation_cm3_s > 0.0) {
            continue;
        }
        let scale = c.ionisation_cm3_s / ions;
        for (dst, v) in source[i * jc..(i + 1) * jc].iter_mut().zip(&snapshot) {
            *dst = scale * v;
        }
        tally[i].add_scaled(&high, scale);
    }
    (source, tally)
}

/// The transported bins below `jc`, top down: each bin's flux u over the column from the
/// two-stream equation (or, `local_only`, each altitude alone) with its `source`, then
/// its collisions tallied into `tally` and cascading into the source of the lower bins.
fn transport_bins(
    deg: &Degradation,
    column: &[TransportAir],
    airs: &[LocalAir],
    jc: usize,
    local_only: bool,
    source: &mut [f64],
    tally: &mut [Tally],
) {
    let n = column.len();
    let e = deg.energies_ev();
    let mut u = vec![0.0; n];
    let mut a = vec![0.0; n];
    let mut thermal = vec![0.0; n];
    let mut extinction = vec![0.0; n];
    let mut rhs = vec![0.0; n];
    let mut scratch = vec![0.0; n];
    let mut inflow = vec![0.0; jc];
    for j in (0..jc).rev() {
        for (i, air) in airs.iter().enumerate() {
            (a[i], thermal[i]) = deg.removal_cm(j, air);
            let back: f64 = (0..3).map(|s| air.densities_cm3[s] * 0.5 * momentum_transfer_cm2(s, e[j])).sum();
            extinction[i] = a[i] + 2.0 * back;
            rhs[i] = source[i * jc + j];
        }
        if local_only {
            for i in 0..n {
                u[i] = if a[i] > 0.0 { rhs[i] / a[i] } else { 0.0 };
            }
        } else {
            solve_two_stream(column, &a, &extinction, &rhs, &mut scratch, &mut u);
        }
        for (i, air) in airs.iter().enumerate() {
            if !(u[i] > 0.0) || !(a[i] > 0.0) {
                continue;
            }
            inflow.fill(0.0);
            deg.collide(j, air, u[i], thermal[i], &mut inflow, &mut tally[i]);
            for (dst, v) in source[i * jc..i * jc + j].iter_mut().zip(&inflow[..j]) {
                *dst += v;
            }
        }
    }
}

/// Finite volumes for `-μ̄² d/dz (1/ext du/dz) + a u = s` on the column's altitudes, with
/// the escape μ̄ u at both ends (φ⁻ = 0 at the top, φ⁺ = 0 at the bottom). The
/// face coefficient takes the geometric mean of the two nodes' extinction (the air
/// thins exponentially). The matrix is an M-matrix (positive diagonal that dominates
/// non-positive neighbours), so the Thomas algorithm needs no pivoting and u ≥ 0.
fn solve_two_stream(
    column: &[TransportAir],
    a: &[f64],
    ext: &[f64],
    s: &[f64],
    c_prime: &mut [f64],
    u: &mut [f64],
) {
    let n = column.len();
    let z = |i: usize| column[i].altitude_cm;
    // Conductance of face i+1/2.
    let face = |i: usize| {
        let ext_face = (ext[i] * ext[i + 1]).sqrt();
        if ext_face > 0.0 { MU * MU / ext_face / (z(i + 1) - z(i)) } else { 0.0 }
    };
    // Forward sweep: row i is -g_lo u[i-1] + diag u[i] - g_hi u[i+1] = rhs.
    let mut g_lo = 0.0;
    let mut d_prime_prev = 0.0;
    for i in 0..n {
        let g_hi = if i + 1 < n { face(i) } else { 0.0 };
        let lo = if i > 0 { z(i - 1) } else { z(i) };
        let hi = if i + 1 < n { z(i + 1) } else { z(i) };
        let volume = 0.5 * (hi - lo);
        let escape = if i == 0 || i + 1 == n { MU } else { 0.0 };
        let diag = g_lo + g_hi + a[i] * volume + escape;
        let rhs = s[i] * volume;
        let (cp_prev, dp_prev) = if i > 0 { (c_prime[i - 1], d_prime_prev) } else { (0.0, 0.0) };
        let denom = diag - g_lo * cp_prev;
        c_prime[i] = if denom > 0.0 { g_hi / denom } else { 0.0 };
        let d = if denom > 0.0 { (rhs + g_lo * dp_prev) / denom } else { 0.0 };
        u[i] = d;
        d_prime_prev = d;
        g_lo = g_hi;
    }
    for i in (0..n.saturating_sub(1)).rev() {
        u[i] += c_prime[i] * u[i + 1];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::Atmosphere;
    use crate::deposition::{Precipitation, Spectrum, fang2010_ionisation};

    /// The crate's atmosphere under a 2 keV Maxwellian of 1 erg cm⁻² s⁻¹, with `ne`
    /// thermal electrons everywhere.
    pub(super) fn column(ne: f64) -> Vec<TransportAir> {
        let bins =
            Precipitation { spectrum: Spectrum::Maxwellian, energy_kev: 2.0, flux_erg_cm2_s: 1.0 }.bins();
        Atmosphere::msis21()
            .samples()
            .iter()
            .map(|s| TransportAir {
                altitude_cm: s.altitude_km * 1e5,
                densities_cm3: [s.n_o_m3 * 1e-6, s.n_o2_m3 * 1e-6, s.n_n2_m3 * 1e-6],
                electron_density_cm3: ne,
                electron_temperature_k: s.temperature_k,
                ionisation_cm3_s: bins.iter().map(|&(e, q)| fang2010_ionisation(s, e, q)).sum(),
            })
            .collect()
    }

    #[test]
    fn without_transport_it_is_the_local_balance() {
        // The same bins and collisions, each altitude alone: q times the local yields
        // per ion pair, to rounding (1e-9; the sums run in another order).
        let col = column(3e4);
        let local = impact_rates(&col, true);
        let deg = Degradation::shared();
        for (c, r) in col.iter().zip(&local).step_by(20) {
            let y = deg.yields(c.densities_cm3, c.electron_density_cm3, c.electron_temperature_k);
            let want = c.ionisation_cm3_s * y.o1d_per_ion_pair;
            assert!((r.o1d / want - 1.0).abs() < 1e-9, "{} km: {} vs {want}", c.altitude_cm / 1e5, r.o1d);
            let want = c.ionisation_cm3_s * y.n2_dissociation_per_ion_pair;
            assert!((r.n2_dissociation / want - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn uniform_air_is_local_away_from_its_ends() {
        // Constant air and source: the exact solution is u = S/A except in boundary
        // layers that decay as exp(-x/L), L a diffusion length (~5 km for one 5 eV bin
        // at 200 km; the cascade through many bins lengthens it: 100 km from an end the
        // difference is still 2.5e-6, so L ≈ 8 km). Air of 200 km over 300 km: within
        // 1e-6 from 130 km inside (exp(-130/8) ≈ 1e-7).
        let mut col = column(3e4);
        let mid = col[120];
        for (i, c) in col.iter_mut().enumerate().take(301) {
            *c = TransportAir { altitude_cm: (100.0 + i as f64) * 1e5, ..mid };
        }
        col.truncate(301);
        let moved = impact_rates(&col, false);
        let local = impact_rates(&col, true);
        for i in 130..=170 {
            assert!(
                (moved[i].o1d / local[i].o1d - 1.0).abs() < 1e-6,
                "{i}: {} vs {}",
                moved[i].o1d,
                local[i].o1d
            );
        }
        // At the ends electrons escape: less O(¹D) there, never more.
        assert!(moved[300].o1d < 0.9 * local[300].o1d && moved[0].o1d < local[0].o1d);
    }

    #[test]
    fn the_yield_falls_above_the_layer_that_stops_the_electrons() {
        // Locally the O(¹D) per ion pair rises from 200 to 250 km (more O, fewer N₂;
        // higher up the loss to the fixed 3e4 cm⁻³ of thermal electrons takes over);
        // with transport the 4-10 eV electrons escape upward and downward from high up,
        // so it falls from 200 km on (GLOW, Solomon et al. 1988, shows the same): at
        // 250 km below the 200 km value, where the local balance has it above, and at
        // 300 km under 0.8 of it. (Measured 2026-12-04: local 0.81 / 0.89 / 0.76, moved
        // 0.78 / 0.65 / 0.43 O(¹D) per ion pair at 200 / 250 / 300 km.)
        let col = column(3e4);
        let moved = impact_rates(&col, false);
        let local = impact_rates(&col, true);
        let y = |r: &[ImpactRates], z: usize| r[z - 80].o1d / col[z - 80].ionisation_cm3_s;
        assert!(y(&local, 250) > y(&local, 200), "local {} {}", y(&local, 250), y(&local, 200));
        assert!(y(&moved, 250) < y(&moved, 200), "moved {} {}", y(&moved, 250), y(&moved, 200));
        assert!(y(&moved, 300) < 0.8 * y(&moved, 200), "moved {} {}", y(&moved, 300), y(&moved, 200));
        // Low down the air stops them where they are born: within 2 % at 130 km.
        assert!((y(&moved, 130) / y(&local, 130) - 1.0).abs() < 0.02);
    }

    #[test]
    fn the_transport_top_barely_matters() {
        // Where the local balance hands over to the transport (module docs): the O(¹D)
        // by impact, column and peak, for 50, 100 and 200 eV.
        let col = column(3e4);
        let summary = |top: f64| {
            let r = impact_rates_from(&col, false, top);
            let total: f64 = r.iter().map(|r| r.o1d).sum();
            let k = (0..r.len()).max_by(|&a, &b| r[a].o1d.total_cmp(&r[b].o1d)).unwrap_or(0);
            (total, k)
        };
        let (base, peak) = summary(100.0);
        for top in [50.0, 200.0] {
            let (total, k) = summary(top);
            assert!((total / base - 1.0).abs() < 0.03, "{top} eV: column {total} vs {base}");
            assert!(k.abs_diff(peak) <= 1, "{top} eV: peak {k} vs {peak}");
        }
    }
}
