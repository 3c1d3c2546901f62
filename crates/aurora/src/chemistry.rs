//! The ion chemistry of the `physical` mode's column and the sources of O(¹D), the
//! upper state of the red 630.0 nm line.
//!
//! At each altitude, given the ionisation of O, O₂ and N₂ by the precipitating
//! electrons, the ions O⁺(⁴S, ²D, ²P), N⁺, N₂⁺, O₂⁺ and NO⁺ are each in photochemical
//! equilibrium (production = loss) and the electron density is their sum (charge
//! neutrality): [`electron_density`] solves that balance. Above ~300 km O⁺ also leaves
//! by diffusion ([`o_plus_diffusion_rate_s`], a local rate). Then N(²D) follows, and the
//! production of O(¹D) by each source of [`O1dSource`]:
//! - electron impact on O (the secondary and degraded primary electrons: per ion pair
//!   from [`crate::degradation`]);
//! - dissociative recombination O₂⁺ + e → O + O(¹D);
//! - N(²D) + O₂ → NO + O(¹D) and N(²D) + O → N + O(¹D);
//! - N⁺ + O₂ → NO⁺ + O(¹D) and O⁺(²D) + O;
//! - dissociation of O₂ through its Schumann-Runge continuum by electron impact;
//! - the O(¹S) → O(¹D) cascade of every 557.7 nm photon.
//!
//! The losses of O(¹D) (radiation and quenching) are [`crate::emission::Line`]'s.
//!
//! Rate coefficients, branching ratios and Einstein coefficients are those compiled in
//! GLOW v0.981's `gchem.f90` (Solomon; each with the laboratory or theoretical source
//! it cites, given here per constant), except O(¹D) + O (see `emission.rs`). Densities
//! are cm⁻³ and rates cm³ s⁻¹ here, the customary unit of these coefficients.
//!
//! Temperatures: the ion and electron temperatures are taken equal to the neutral
//! temperature of the atmosphere table (in aurora Tₑ runs above Tₙ above ~150 km; the
//! table has no Tₑ, and the coefficients that depend on it most, the dissociative
//! recombination rates, enter the red line mostly through the O₂⁺ production, which is
//! recombined either way).
//!
//! ```
//! use phenomena_aurora::chemistry::{Air, IonProduction, electron_density};
//! // 150 km: ionisation of 1000 cm⁻³ s⁻¹, mostly N₂.
//! let air = Air {
//!     n_o: 1.6e10, n_o2: 2.0e9, n_n2: 2.6e10, n_n: 2.7e6, n_no: 1.5e7,
//!     temperature_k: 730.0, o_plus_diffusion_s: 0.0, o_plus_background: 0.0,
//! };
//! let p = IonProduction { o: 200.0, o2: 100.0, n2: 700.0 };
//! let (ne, ions) = electron_density(&p, &air, 0.0);
//! assert!((ions.total() / ne - 1.0).abs() < 1e-9); // charge neutrality
//! assert!((3e4..3e5).contains(&ne));
//! ```

/// The air at one altitude for the chemistry, cm⁻³ and K.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Air {
    /// Atomic oxygen.
    pub n_o: f64,
    /// Molecular oxygen.
    pub n_o2: f64,
    /// Molecular nitrogen.
    pub n_n2: f64,
    /// Atomic nitrogen N(⁴S).
    pub n_n: f64,
    /// Nitric oxide.
    pub n_no: f64,
    /// Neutral temperature, K (also used for the ions and electrons).
    pub temperature_k: f64,
    /// Loss rate of O⁺ by ambipolar diffusion along B, s⁻¹ (0: none; see
    /// [`o_plus_diffusion_rate_s`]).
    pub o_plus_diffusion_s: f64,
    /// O⁺ of the night F region ([`crate::atmosphere::NightIonosphere`]), cm⁻³: kept up
    /// by plasma from elsewhere, so it enters as the source that holds this density
    /// against O⁺'s chemical and diffusive loss (0: the aurora alone).
    pub o_plus_background: f64,
}

/// A local stand-in for the ambipolar diffusion of O⁺ along a vertical field line, s⁻¹:
/// D_a / H_p² with D_a = k (Tₑ + Tᵢ) / (m_O ν) and the plasma scale height
/// H_p = k (Tₑ + Tᵢ) / (m_O g), so m_O g² / (k (Tₑ + Tᵢ) ν), for Tₑ = Tᵢ = Tₙ; ν is the
/// O⁺-O resonant charge-exchange collision frequency 3.67e-11 n_O T^0.5
/// (1 - 0.064 log₁₀ T)² s⁻¹ (n_O in cm⁻³; Schunk and Nagy 2009, Ionospheres, Table 4.5).
/// An order-of-magnitude rate, not a transport solution: it is what makes the F2 peak
/// where it equals the chemical loss (near 300 km), and above that it keeps the
/// equilibrium O⁺, whose chemical loss falls with N₂ and O₂, from piling up without
/// bound (the real topside is fed by diffusion from below and the plasmasphere).
pub fn o_plus_diffusion_rate_s(n_o_cm3: f64, temperature_k: f64, gravity_m_s2: f64) -> f64 {
    const O_MASS_KG: f64 = 15.999 * 1.660_539_066_60e-27;
    const BOLTZMANN_J_PER_K: f64 = 1.380_649e-23;
    let t = temperature_k;
    let nu = 3.67e-11 * n_o_cm3 * t.sqrt() * (1.0 - 0.064 * t.log10()).powi(2);
    if !(nu > 0.0) {
        return 0.0;
    }
    O_MASS_KG * gravity_m_s2 * gravity_m_s2 / (2.0 * BOLTZMANN_J_PER_K * t * nu)
}

/// Ionisation rates of O, O₂ and N₂ by electron impact, cm⁻³ s⁻¹.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IonProduction {
    /// Of O.
    pub o: f64,
    /// Of O₂.
    pub o2: f64,
    /// Of N₂.
    pub n2: f64,
}

/// Rate coefficients at one temperature, cm³ s⁻¹ (GLOW v0.981 `gchem.f90`'s k1-k39;
/// the source each cites is in its field's comment). With Tᵢ = Tₙ the effective
/// temperatures of the ion-neutral reactions are all Tₙ.
#[derive(Clone, Copy, Debug)]
struct Rates {
    /// O⁺ + N₂ → NO⁺ + N: St. Maurice and Torr (1978), from Albritton et al. (1977).
    op_n2: f64,
    /// O⁺ + O₂ → O₂⁺ + O: Chen et al. (1978) with St. Maurice and Torr (1978).
    op_o2: f64,
    /// N₂⁺ + O → NO⁺ + N(²D): fit to McFarland et al. (1974).
    n2p_o: f64,
    /// N₂⁺ + O₂ → O₂⁺ + N₂: McFarland et al. (1973), 5.0e-11 (300/T)^0.8.
    n2p_o2: f64,
    /// N₂⁺ + O → O⁺ + N₂: Torr (1985), 2.0e-11.
    n2p_o_charge: f64,
    /// N(²D) + O₂ → NO + O: Lin and Kaufman (1971), cf. Piper et al. (1987), 6.0e-12.
    n2d_o2: f64,
    /// N(²D) + O → N + O: Fell et al. (1990), 6.9e-13.
    n2d_o: f64,
    /// N(²D) + e: Frederick and Rusch (1977), 5.5e-10 (Tₑ/300)^0.5.
    n2d_e: f64,
    /// N(²D) + NO: Black et al. (1969), 7.0e-11.
    n2d_no: f64,
    /// O⁺ + N(²D) → N⁺ + O: Bates (1989), 1.3e-10.
    op_n2d: f64,
    /// O⁺(²D) + N₂ → N₂⁺ + O: Johnsen and Biondi (1980), 8.0e-10.
    op2d_n2: f64,
    /// O⁺(²D) + O₂ → O₂⁺ + O: Johnsen and Biondi (1980), 7.0e-10.
    op2d_o2: f64,
    /// O⁺(²D) + e → O⁺(⁴S): Henry et al. (1969), 6.6e-8 (300/Tₑ)^0.5.
    op2d_e: f64,
    /// O⁺(²D) + O → O⁺(⁴S) + O: Torr and Torr (1980), 1.0e-11.
    op2d_o: f64,
    /// O⁺(²P) + N₂ → N₂⁺ + O: Rusch et al. (1977), 4.8e-10.
    op2p_n2: f64,
    /// O⁺(²P) + O₂ → O₂⁺ + O: Link (1982), 4.8e-10.
    op2p_o2: f64,
    /// O⁺(²P) + e: Henry et al. (1969), 1.7e-7 (300/Tₑ)^0.5.
    op2p_e: f64,
    /// O⁺(²P) + O → O⁺(⁴S) + O: Rusch et al. (1977), 5.2e-11.
    op2p_o: f64,
    /// NO⁺ + e → N + O: Walls and Dunn (1974), Torr et al. (1977), Alge et al. (1983),
    /// 4.2e-7 (300/Tₑ)^0.85.
    nop_e: f64,
    /// N₂⁺ + e → N + N: Mehr and Biondi (1969), 1.8e-7 (300/Tₑ)^0.39.
    n2p_e: f64,
    /// O₂⁺ + e → O + O: Mehr and Biondi (1969), Walls and Dunn (1974), Alge et al.
    /// (1983), 1.95e-7 (300/Tₑ)^0.7 below 1200 K, 1.6e-7 (300/Tₑ)^0.55 above.
    o2p_e: f64,
    /// N⁺ + O₂ → products: Langford et al. (1985), 6.0e-10.
    np_o2: f64,
    /// N⁺ + O → O⁺ + N: Torr (1985), 1.0e-12.
    np_o: f64,
    /// O₂⁺ + NO → NO⁺ + O₂: Lindinger and Ferguson (1974), 4.4e-10.
    o2p_no: f64,
    /// O₂⁺ + N → NO⁺ + O: Fehsenfeld (1977), 1.2e-10.
    o2p_n: f64,
    /// O⁺ + NO → NO⁺ + O: St. Maurice and Torr (1978).
    op_no: f64,
    /// N(²P) + O: Zipf et al. (1980), Young and Dunn (1975), 1.2e-11.
    n2p_state_o: f64,
    /// N(²P) + O₂: Zipf et al. (1980), Rawlins (1988), 2.0e-12.
    n2p_state_o2: f64,
    /// N(²P) + NO: Rees and Jones (1973), Zipf et al. (1980), 1.8e-10.
    n2p_state_no: f64,
}

impl Rates {
    fn new(temperature_k: f64) -> Self {
        let t = temperature_k / 300.0;
        let op_n2 = if t < 5.6667 {
            1.533e-12 - 5.92e-13 * t + 8.6e-14 * t * t
        } else {
            2.73e-12 - 1.155e-12 * t + 1.483e-13 * t * t
        };
        let op_o2 = if t < 6.6667 {
            3.53e-11 - 1.84e-11 * t + 4.62e-12 * t.powi(2) - 4.95e-13 * t.powi(3) + 2.00e-14 * t.powi(4)
        } else {
            2.82e-11 - 7.74e-12 * t + 1.073e-12 * t.powi(2) - 5.17e-14 * t.powi(3) + 9.65e-16 * t.powi(4)
        };
        let op_no = if t < 5.0 {
            8.36e-13 - 2.02e-13 * t + 6.95e-14 * t * t
        } else {
            5.33e-13 - 1.64e-14 * t + 4.72e-14 * t * t - 7.05e-16 * t.powi(3)
        };
        Self {
            op_n2,
            op_o2,
            n2p_o: 1.793e-10 - 6.242e-11 * t + 1.225e-11 * t.powi(2) - 1.016e-12 * t.powi(3)
                + 3.087e-14 * t.powi(4),
            n2p_o2: 5.0e-11 * t.powf(-0.8),
            n2p_o_charge: 2.0e-11,
            n2d_o2: 6.0e-12,
            n2d_o: 6.9e-13,
            n2d_e: 5.5e-10 * t.sqrt(),
            n2d_no: 7.0e-11,
            op_n2d: 1.3e-10,
            op2d_n2: 8.0e-10,
            op2d_o2: 7.0e-10,
            op2d_e: 6.6e-8 / t.sqrt(),
            op2d_o: 1.0e-11,
            op2p_n2: 4.8e-10,
            op2p_o2: 4.8e-10,
            op2p_e: 1.7e-7 / t.sqrt(),
            op2p_o: 5.2e-11,
            nop_e: 4.2e-7 * t.powf(-0.85),
            n2p_e: 1.8e-7 * t.powf(-0.39),
            o2p_e: if temperature_k >= 1200.0 { 1.6e-7 * t.powf(-0.55) } else { 1.95e-7 * t.powf(-0.7) },
            np_o2: 6.0e-10,
            np_o: 1.0e-12,
            o2p_no: 4.4e-10,
            o2p_n: 1.2e-10,
            op_no,
            n2p_state_o: 1.2e-11,
            n2p_state_o2: 2.0e-12,
            n2p_state_no: 1.8e-10,
        }
    }
}

// Branching ratios (GLOW v0.981 `gchem.f90`'s B, with its sources).
/// O(¹D) per O₂⁺ dissociative recombination (B2: Abreu et al. 1986).
pub const O1D_PER_O2P_RECOMBINATION: f64 = 1.20;
/// N(²D) per NO⁺ dissociative recombination (B3: Kley et al. 1976).
const N2D_PER_NOP_RECOMBINATION: f64 = 0.76;
/// N(²D) per N₂⁺ dissociative recombination (B4: Queffelec et al. 1985).
const N2D_PER_N2P_RECOMBINATION: f64 = 1.85;
/// N(²D) per N₂⁺ + O → NO⁺ + N (B5: Frederick and Rusch 1977).
const N2D_PER_N2P_O: f64 = 1.0;
/// O(¹D) per N(²D) + O₂ (B6: Link 1983; Langford et al. 1985).
pub const O1D_PER_N2D_O2: f64 = 0.10;
/// O(¹D) per O⁺(²D) + O (B7, as GLOW has it, no source given).
const O1D_PER_OP2D_O: f64 = 0.50;
/// O⁺(²D) per O⁺(²P) + e (B8: Link 1982).
const OP2D_PER_OP2P_E: f64 = 0.81;
/// O⁺(²P), O⁺(²D), O⁺(⁴S) per O ionisation (B9-B11: Gérard and Rusch 1979; Jones 1975).
const O_ION_STATES: [f64; 3] = [0.20, 0.32, 0.48];
/// O⁺(²P), O⁺(²D), O⁺(⁴S) per O₂ ionisation, dissociative (B12-B14: Link 1982, "a
/// guess of 0.3/3"); the rest, 0.7, is O₂⁺.
const O2_DISSOCIATIVE_ION_STATES: [f64; 3] = [0.10, 0.10, 0.10];
/// N⁺ per N₂ ionisation (dissociative ionisation; B15: Richards and Torr 1985).
const NP_PER_N2_ION: f64 = 0.16;
/// N(²D) per N⁺ so made (B16: Zipf et al. 1980).
const N2D_PER_N2_DISSOCIATIVE_ION: f64 = 0.50;
/// O(¹D), NO⁺ and O₂⁺ per N⁺ + O₂ (B17, B21, B22: Langford et al. 1985).
const O1D_PER_NP_O2: f64 = 0.30;
const NOP_PER_NP_O2: f64 = 0.43;
const O2P_PER_NP_O2: f64 = 0.51;
/// The rest of N⁺ + O₂, O⁺ + NO, so that charge is conserved (GLOW drops it).
const OP_PER_NP_O2: f64 = 1.0 - NOP_PER_NP_O2 - O2P_PER_NP_O2;
/// N(²P) per N₂⁺ dissociative recombination (B23: Queffelec et al. 1985).
const N2P_STATE_PER_N2P_RECOMBINATION: f64 = 0.10;
/// N(²D) and N(²P) per electron-impact dissociation of N₂ (B25, B26: Zipf et al. 1980).
const N2D_PER_N2_DISSOCIATION: f64 = 0.54;
const N2P_STATE_PER_N2_DISSOCIATION: f64 = 0.44;
/// N(²D) per N(²P) + O (B29, GLOW's value, no source given).
const N2D_PER_N2P_STATE_O: f64 = 1.0;

// Einstein coefficients, s⁻¹ (GLOW v0.981 `gchem.f90`'s A).
/// N(²D) → N(⁴S), 520.0 nm (A1: Wiese et al. 1966).
const A_N2D: f64 = 1.07e-5;
/// O⁺(²D) → O⁺(⁴S), 372.6 nm (A6: Kernahan and Pang 1975).
const A_OP2D: f64 = 9.7e-5;
/// O⁺(²P) → O⁺(⁴S), 247.0 nm (A7: Wiese et al. 1966) and → O⁺(²D), 732 nm (A8).
const A_OP2P_4S: f64 = 0.0479;
const A_OP2P_2D: f64 = 0.1712;
/// N(²P) → N(⁴S), 346.6 nm, and → N(²D), 1040 nm (A11, A12: Chamberlain 1961).
const A_N2P_4S: f64 = 0.0054;
const A_N2P_2D: f64 = 0.079;

/// Ion densities in photochemical equilibrium, cm⁻³.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IonDensities {
    /// O⁺(⁴S), the ground state.
    pub o_plus: f64,
    /// O⁺(²D).
    pub o_plus_2d: f64,
    /// O⁺(²P).
    pub o_plus_2p: f64,
    /// N⁺.
    pub n_plus: f64,
    /// N₂⁺.
    pub n2_plus: f64,
    /// O₂⁺.
    pub o2_plus: f64,
    /// NO⁺.
    pub no_plus: f64,
}

impl IonDensities {
    /// All positive ions: the electron density, by charge neutrality.
    pub fn total(&self) -> f64 {
        self.o_plus
            + self.o_plus_2d
            + self.o_plus_2p
            + self.n_plus
            + self.n2_plus
            + self.o2_plus
            + self.no_plus
    }
}

/// The ions in equilibrium for electron density `ne` and N(²D) density `n2d` (cm⁻³).
/// Each is its production over its loss, taken in an order in which every production
/// uses ions already found.
fn ions_at(p: &IonProduction, a: &Air, r: &Rates, ne: f64, n2d: f64) -> IonDensities {
    let [o2p_of_o, o2d_of_o, o4s_of_o] = O_ION_STATES;
    let [o2p_of_o2, o2d_of_o2, o4s_of_o2] = O2_DISSOCIATIVE_ION_STATES;
    let o_plus_2p = (o2p_of_o * p.o + o2p_of_o2 * p.o2)
        / (r.op2p_n2 * a.n_n2
            + r.op2p_o2 * a.n_o2
            + r.op2p_o * a.n_o
            + r.op2p_e * ne
            + A_OP2P_2D
            + A_OP2P_4S);
    let o_plus_2d =
        (o2d_of_o * p.o + o2d_of_o2 * p.o2 + (OP2D_PER_OP2P_E * r.op2p_e * ne + A_OP2P_2D) * o_plus_2p)
            / (r.op2d_n2 * a.n_n2 + r.op2d_o2 * a.n_o2 + r.op2d_o * a.n_o + r.op2d_e * ne + A_OP2D);
    let n2_plus = ((1.0 - NP_PER_N2_ION) * p.n2 + (r.op2d_n2 * o_plus_2d + r.op2p_n2 * o_plus_2p) * a.n_n2)
        / ((r.n2p_o + r.n2p_o_charge) * a.n_o + r.n2p_o2 * a.n_o2 + r.n2p_e * ne);
    // O⁺(⁴S) and N⁺ feed each other (O⁺ + N(²D) → N⁺; N⁺ + O, N⁺ + O₂ → O⁺): solved
    // together. c is the share of N⁺ that comes back as O⁺.
    let n_plus_loss = r.np_o2 * a.n_o2 + r.np_o * a.n_o;
    let c = r.np_o * a.n_o / n_plus_loss + OP_PER_NP_O2 * r.np_o2 * a.n_o2 / n_plus_loss;
    let o_plus_other = o4s_of_o * p.o
        + o4s_of_o2 * p.o2
        + (r.op2d_e * ne + r.op2d_o * a.n_o + A_OP2D) * o_plus_2d
        + ((1.0 - OP2D_PER_OP2P_E) * r.op2p_e * ne + r.op2p_o * a.n_o + A_OP2P_4S) * o_plus_2p
        + r.n2p_o_charge * n2_plus * a.n_o;
    let o_plus_kept = r.op_n2 * a.n_n2 + r.op_o2 * a.n_o2 + r.op_no * a.n_no + a.o_plus_diffusion_s;
    let o_plus_other = o_plus_other + a.o_plus_background * o_plus_kept;
    let o_plus_loss = o_plus_kept + r.op_n2d * n2d;
    let n_plus_made = NP_PER_N2_ION * p.n2;
    let o_plus = (o_plus_other + c * n_plus_made) / (o_plus_loss - c * r.op_n2d * n2d);
    let n_plus = (n_plus_made + r.op_n2d * n2d * o_plus) / n_plus_loss;
    let o2_plus = ((1.0 - o2p_of_o2 - o2d_of_o2 - o4s_of_o2) * p.o2
        + (r.op_o2 * o_plus + r.op2d_o2 * o_plus_2d + r.op2p_o2 * o_plus_2p + r.n2p_o2 * n2_plus) * a.n_o2
        + O2P_PER_NP_O2 * r.np_o2 * n_plus * a.n_o2)
        / (r.o2p_e * ne + r.o2p_no * a.n_no + r.o2p_n * a.n_n);
    let no_plus = (r.op_n2 * o_plus * a.n_n2
        + r.op_no * o_plus * a.n_no
        + r.n2p_o * n2_plus * a.n_o
        + NOP_PER_NP_O2 * r.np_o2 * n_plus * a.n_o2
        + (r.o2p_no * a.n_no + r.o2p_n * a.n_n) * o2_plus)
        / (r.nop_e * ne);
    IonDensities { o_plus, o_plus_2d, o_plus_2p, n_plus, n2_plus, o2_plus, no_plus }
}

/// The electron density (cm⁻³) at which the ions in equilibrium add up to it, and those
/// ions, for ionisation `p` in air `a` with `n2d` cm⁻³ of N(²D). Σ ions(nₑ) - nₑ is
/// positive at the bracket's low end and negative at its high end (recombination grows
/// with nₑ), and bisection on log nₑ in [1e-3, 1e9] cm⁻³ finds a root to 1e-12
/// relative. Not every ion falls as nₑ rises (more electrons quench O⁺(²D, ²P) into
/// O⁺(⁴S) instead of letting them charge-transfer to N₂⁺), so a single root is not
/// proven, only found. No ionisation and no night F region (`Air::o_plus_background`):
/// no electrons.
pub fn electron_density(p: &IonProduction, a: &Air, n2d: f64) -> (f64, IonDensities) {
    if !(p.o + p.o2 + p.n2 > 0.0) && !(a.o_plus_background > 0.0) {
        return (0.0, IonDensities::default());
    }
    let r = Rates::new(a.temperature_k);
    let (mut lo, mut hi) = (1e-3f64.ln(), 1e9f64.ln());
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        let ne = mid.exp();
        if ions_at(p, a, &r, ne, n2d).total() > ne {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 {
            break;
        }
    }
    let ne = (0.5 * (lo + hi)).exp();
    // Report the ions at this nₑ, and nₑ as their sum (equal to 1e-12).
    let ions = ions_at(p, a, &r, ne, n2d);
    (ions.total(), ions)
}

/// The sources of O(¹D), in the order of [`O1dSource::ALL`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum O1dSource {
    /// Electron impact on O by secondary and degraded primary electrons.
    ElectronImpact,
    /// O₂⁺ + e → O + O(¹D).
    DissociativeRecombination,
    /// N(²D) + O₂ → NO + O(¹D).
    NitrogenWithO2,
    /// N(²D) + O → N(⁴S) + O(¹D) (GLOW's B20 = 0.1, no source given).
    NitrogenWithO,
    /// N⁺ + O₂ → NO⁺ + O(¹D).
    NitrogenIonWithO2,
    /// O⁺(²D) + O → O⁺(⁴S) + O(¹D).
    OxygenIonWithO,
    /// e + O₂ → e + O + O(¹D) through the Schumann-Runge continuum.
    O2Dissociation,
    /// O(¹S) → O(¹D) + 557.7 nm.
    O1sCascade,
}

impl O1dSource {
    /// All sources.
    pub const ALL: [O1dSource; 8] = [
        O1dSource::ElectronImpact,
        O1dSource::DissociativeRecombination,
        O1dSource::NitrogenWithO2,
        O1dSource::NitrogenWithO,
        O1dSource::NitrogenIonWithO2,
        O1dSource::OxygenIonWithO,
        O1dSource::O2Dissociation,
        O1dSource::O1sCascade,
    ];

    /// Position in [`O1dSource::ALL`].
    pub fn index(self) -> usize {
        Self::ALL.iter().position(|&s| s == self).unwrap_or(0)
    }

    /// Short name (CSV column).
    pub fn name(self) -> &'static str {
        match self {
            O1dSource::ElectronImpact => "electron_impact",
            O1dSource::DissociativeRecombination => "o2p_recombination",
            O1dSource::NitrogenWithO2 => "n2d_o2",
            O1dSource::NitrogenWithO => "n2d_o",
            O1dSource::NitrogenIonWithO2 => "np_o2",
            O1dSource::OxygenIonWithO => "op2d_o",
            O1dSource::O2Dissociation => "o2_dissociation",
            O1dSource::O1sCascade => "o1s_cascade",
        }
    }
}

/// Everything at one altitude that the red line needs: the ionisation, electron impact
/// yields, and O(¹S) made.
#[derive(Clone, Copy, Debug)]
pub struct Column {
    /// The air.
    pub air: Air,
    /// Ionisation of O, O₂, N₂, cm⁻³ s⁻¹.
    pub production: IonProduction,
    /// O(¹S) made that radiates 557.7 nm and so lands in O(¹D), cm⁻³ s⁻¹.
    pub o1s_cascade: f64,
    /// Electron impact rates from the transport ([`crate::transport`]); `None`: the
    /// local balance's yields per ion pair at this altitude.
    pub impact: Option<crate::transport::ImpactRates>,
}

/// The chemistry's result at one altitude.
#[derive(Clone, Copy, Debug, Default)]
pub struct RedLineSources {
    /// Electron density, cm⁻³.
    pub electron_density_cm3: f64,
    /// The ions, cm⁻³.
    pub ions: IonDensities,
    /// N(²D), cm⁻³.
    pub n2d_cm3: f64,
    /// O(¹D) production per source ([`O1dSource::ALL`] order), cm⁻³ s⁻¹.
    pub o1d_production: [f64; 8],
}

/// Passes of the fixed point nₑ → electron-impact yields and N(²D) → nₑ (O⁺ + N(²D)
/// couples them above ~250 km); the test `the_chemistry_reaches_its_fixed_point` shows
/// nₑ changing by < 1e-3 after these.
const PASSES: usize = 4;

/// Solve the chemistry at every altitude of `column` (independent altitudes, in
/// parallel; each is computed the same way whatever the thread count).
pub fn red_line_sources(column: &[Column]) -> Vec<RedLineSources> {
    use rayon::prelude::*;
    column.par_iter().map(red_line_at).collect()
}

/// [`red_line_sources`] at one altitude.
pub fn red_line_at(c: &Column) -> RedLineSources {
    let deg = crate::degradation::Degradation::shared();
    let a = &c.air;
    let q = c.production.o + c.production.o2 + c.production.n2;
    let r = Rates::new(a.temperature_k);
    let mut n2d = 0.0;
    let (mut ne, mut ions) = (0.0, IonDensities::default());
    // Electron impact: O(¹D), O₂ and N₂ dissociation, cm⁻³ s⁻¹.
    let mut impact = c.impact.unwrap_or_default();
    for pass in 0..PASSES {
        (ne, ions) = electron_density(&c.production, a, n2d);
        if c.impact.is_none() && (pass == 0 || pass == PASSES - 1) {
            let y = deg.yields([a.n_o, a.n_o2, a.n_n2], ne, a.temperature_k);
            impact = crate::transport::ImpactRates {
                o1d: q * y.o1d_per_ion_pair,
                o2_dissociation: q * y.o2_dissociation_per_ion_pair,
                n2_dissociation: q * y.n2_dissociation_per_ion_pair,
                ionisation: q,
            };
        }
        n2d = nitrogen_2d(c, &r, &ions, ne, impact.n2_dissociation);
    }
    let (o, o2) = (a.n_o, a.n_o2);
    let mut o1d = [0.0; 8];
    o1d[O1dSource::ElectronImpact.index()] = impact.o1d;
    o1d[O1dSource::DissociativeRecombination.index()] =
        O1D_PER_O2P_RECOMBINATION * r.o2p_e * ions.o2_plus * ne;
    o1d[O1dSource::NitrogenWithO2.index()] = O1D_PER_N2D_O2 * r.n2d_o2 * n2d * o2;
    o1d[O1dSource::NitrogenWithO.index()] = 0.10 * r.n2d_o * n2d * o;
    o1d[O1dSource::NitrogenIonWithO2.index()] = O1D_PER_NP_O2 * r.np_o2 * ions.n_plus * o2;
    o1d[O1dSource::OxygenIonWithO.index()] = O1D_PER_OP2D_O * r.op2d_o * ions.o_plus_2d * o;
    o1d[O1dSource::O2Dissociation.index()] = impact.o2_dissociation;
    o1d[O1dSource::O1sCascade.index()] = c.o1s_cascade;
    RedLineSources { electron_density_cm3: ne, ions, n2d_cm3: n2d, o1d_production: o1d }
}

/// N(²D) in equilibrium, cm⁻³, given the ions, nₑ and the electron-impact
/// dissociation rate of N₂ (cm⁻³ s⁻¹). N(²P) on the way is in equilibrium too.
fn nitrogen_2d(c: &Column, r: &Rates, ions: &IonDensities, ne: f64, n2_dissociation: f64) -> f64 {
    let a = &c.air;
    let n2p_state = (N2P_STATE_PER_N2_DISSOCIATION * n2_dissociation
        + N2P_STATE_PER_N2P_RECOMBINATION * r.n2p_e * ions.n2_plus * ne)
        / (r.n2p_state_o * a.n_o + r.n2p_state_o2 * a.n_o2 + r.n2p_state_no * a.n_no + A_N2P_4S + A_N2P_2D);
    let production = N2D_PER_N2_DISSOCIATION * n2_dissociation
        + N2D_PER_N2_DISSOCIATIVE_ION * NP_PER_N2_ION * c.production.n2
        + N2D_PER_NOP_RECOMBINATION * r.nop_e * ions.no_plus * ne
        + N2D_PER_N2P_RECOMBINATION * r.n2p_e * ions.n2_plus * ne
        + N2D_PER_N2P_O * r.n2p_o * ions.n2_plus * a.n_o
        + (N2D_PER_N2P_STATE_O * r.n2p_state_o * a.n_o + A_N2P_2D) * n2p_state;
    let loss = r.n2d_o2 * a.n_o2
        + r.n2d_o * a.n_o
        + r.n2d_e * ne
        + r.n2d_no * a.n_no
        + r.op_n2d * ions.o_plus
        + A_N2D;
    production / loss
}

#[cfg(test)]
mod tests {
    use super::*;

    fn air_at(z: f64) -> Air {
        let s = crate::atmosphere::Atmosphere::msis21().at(z);
        let m = crate::atmosphere::MinorSpecies::msis21().at(z);
        Air {
            n_o: s.n_o_m3 * 1e-6,
            n_o2: s.n_o2_m3 * 1e-6,
            n_n2: s.n_n2_m3 * 1e-6,
            n_n: m.n_n_m3 * 1e-6,
            n_no: m.n_no_m3 * 1e-6,
            temperature_k: s.temperature_k,
            o_plus_diffusion_s: 0.0,
            o_plus_background: 0.0,
        }
    }

    #[test]
    fn the_electron_density_balances_production_and_recombination() {
        // Conservation: in equilibrium every ion pair made is recombined, so the
        // ionisation rate equals the dissociative recombination of the molecular ions
        // (the atomic ions are only converted, never recombined here). And nₑ is the
        // root: Σ ions(nₑ) = nₑ.
        for (z, q) in [(100.0, 300.0), (120.0, 4000.0), (180.0, 500.0), (300.0, 10.0)] {
            let a = air_at(z);
            let p = IonProduction { o: 0.2 * q, o2: 0.2 * q, n2: 0.6 * q };
            let (ne, ions) = electron_density(&p, &a, 0.0);
            assert!((ions.total() / ne - 1.0).abs() < 1e-9, "{z} km");
            let r = Rates::new(a.temperature_k);
            let recombined = (r.nop_e * ions.no_plus + r.o2p_e * ions.o2_plus + r.n2p_e * ions.n2_plus) * ne;
            assert!((recombined / q - 1.0).abs() < 1e-6, "{z} km: {recombined} vs {q}");
            // Where molecular ions dominate, nₑ ≈ √(q/α) within the spread of α.
            if z < 150.0 {
                let alpha_range = (r.n2p_e.min(r.o2p_e), r.nop_e);
                assert!(ne < (q / alpha_range.0).sqrt() && ne > (q / alpha_range.1).sqrt(), "{z} km: {ne}");
            }
        }
        let (ne, _) = electron_density(&IonProduction::default(), &air_at(150.0), 0.0);
        assert_eq!(ne, 0.0);
    }

    #[test]
    fn every_source_is_positive_and_oxygen_impact_leads_up_high() {
        for (z, q) in [(110.0, 5000.0), (150.0, 1500.0), (220.0, 100.0), (350.0, 2.0)] {
            let a = air_at(z);
            let c = Column {
                air: a,
                production: IonProduction { o: 0.3 * q, o2: 0.1 * q, n2: 0.6 * q },
                o1s_cascade: 0.0,
                impact: None,
            };
            let s = red_line_at(&c);
            assert!(
                s.o1d_production.iter().all(|&p| p >= 0.0 && p.is_finite()),
                "{z}: {:?}",
                s.o1d_production
            );
            assert!(s.n2d_cm3 > 0.0 && s.electron_density_cm3 > 0.0);
            if z > 200.0 {
                let impact = s.o1d_production[O1dSource::ElectronImpact.index()];
                assert!(s.o1d_production.iter().all(|&p| p <= impact), "{z}: {:?}", s.o1d_production);
            }
        }
    }

    #[test]
    fn the_chemistry_reaches_its_fixed_point() {
        // Another pass of nₑ → yields, N(²D) → nₑ changes nₑ by < 1e-3.
        for (z, q) in [(130.0, 3000.0), (250.0, 60.0), (400.0, 1.0)] {
            let a = air_at(z);
            let c = Column {
                air: a,
                production: IonProduction { o: 0.5 * q, o2: 0.05 * q, n2: 0.45 * q },
                o1s_cascade: 0.0,
                impact: None,
            };
            let s = red_line_at(&c);
            let (again, _) = electron_density(&c.production, &a, s.n2d_cm3);
            assert!((again / s.electron_density_cm3 - 1.0).abs() < 1e-3, "{z} km");
        }
    }
}
