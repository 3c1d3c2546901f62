//! The physical mode's column model against an independent 1-D auroral model (issue 20):
//! NCAR GLOW v0.981, run by `tools/glow-ref` (our driver; GLOW's source is not in the
//! repository) for Maxwellian electrons of E0 = 1, 2, 5 keV at 1 erg cm⁻² s⁻¹, 65° N,
//! winter local midnight, F10.7 = 100, Ap = 10. Its profiles are committed in
//! `tests/data/glow/` (provenance in its README).
//!
//! This is model against model: ours runs over its own NRLMSIS 2.1 table (69.6° N,
//! F10.7 = 150, Ap = 15; `crates/aurora/data/`), GLOW over its bundled NRLMSISE-00 and
//! IRI-90. The tolerances are the issue's own ("Done when"): 427.8 and 557.7 nm peaks
//! within 5 km, 557.7/427.8 within ±30 %, the 427.8 column per erg within ±30 %, the
//! 630.0/427.8 column ratio within ±50 %, the 630.0 nm peak within 15 km. Nothing in our
//! model is fitted to these numbers; they are only compared.
//!
//! GLOW's columns include its night background (IRI's F region gives 17.7 R of 630.0 nm
//! without precipitation, peaking at 272 km); ours has no background ionosphere. The
//! ratio is checked against the full and the background-subtracted GLOW column (both
//! must pass). The 630.0 nm peak: see `red_line_peaks`.

use phenomena_aurora::atmosphere::Atmosphere;
use phenomena_aurora::chemistry::O1dSource;
use phenomena_aurora::deposition::{ColumnModel, Precipitation, Spectrum, Yields};
use phenomena_aurora::emission::Line;

/// One GLOW profile: altitude (km) and named columns.
struct Glow {
    z_km: Vec<f64>,
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Glow {
    fn load(name: &str) -> Glow {
        let path = format!("{}/../../tests/data/glow/{name}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let mut lines = text.lines().filter(|l| !l.starts_with('#'));
        let header: Vec<String> = lines.next().expect("header").split(',').map(str::to_string).collect();
        let rows: Vec<Vec<f64>> =
            lines.map(|l| l.split(',').map(|f| f.parse::<f64>().expect("number")).collect()).collect();
        let z_km = rows.iter().map(|r| r[0]).collect();
        Glow { z_km, header, rows }
    }

    fn col(&self, name: &str) -> Vec<f64> {
        let k = self.header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"));
        self.rows.iter().map(|r| r[k]).collect()
    }

    /// Trapezoid column, photons cm⁻² s⁻¹ (km -> cm: 1e5), as `summary.txt` defines it.
    fn column(&self, name: &str) -> f64 {
        trapezoid(&self.z_km, &self.col(name))
    }

    /// Grid altitude of the largest value, km.
    fn peak(&self, name: &str) -> f64 {
        peak(&self.z_km, &self.col(name))
    }
}

fn trapezoid(z: &[f64], v: &[f64]) -> f64 {
    z.windows(2).zip(v.windows(2)).map(|(z, v)| 0.5 * (v[0] + v[1]) * (z[1] - z[0]) * 1e5).sum()
}

fn peak(z: &[f64], v: &[f64]) -> f64 {
    let k = (0..v.len()).max_by(|&a, &b| v[a].total_cmp(&v[b])).unwrap_or(0);
    z[k]
}

fn ours(e0: f64) -> ColumnModel {
    ColumnModel::new(
        Atmosphere::msis21(),
        &Precipitation { spectrum: Spectrum::Maxwellian, energy_kev: e0, flux_erg_cm2_s: 1.0 },
        &Yields::default(),
    )
}

/// The comparison for one spectrum: (ours, GLOW) of each checked quantity.
struct Row {
    e0: f64,
    col_428: (f64, f64),
    ratio_558: (f64, f64),
    ratio_630: (f64, f64),
    ratio_630_no_background: f64,
    peaks: [(f64, f64); 3],
}

fn compare(e0: f64) -> Row {
    let m = ours(e0);
    let g = Glow::load(&format!("glow_E{e0}keV.csv"));
    let bg = Glow::load("glow_noprecip.csv");
    let c = |l: Line| m.column_photons_cm2_s(l);
    let (g428, g558, g630) = (g.column("ver_4278"), g.column("ver_5577"), g.column("ver_6300"));
    Row {
        e0,
        col_428: (c(Line::N2p428), g428),
        ratio_558: (c(Line::O557) / c(Line::N2p428), g558 / g428),
        ratio_630: (c(Line::O630) / c(Line::N2p428), g630 / g428),
        ratio_630_no_background: (g630 - bg.column("ver_6300")) / g428,
        peaks: [
            (m.peak_altitude_km(Line::N2p428), g.peak("ver_4278")),
            (m.peak_altitude_km(Line::O557), g.peak("ver_5577")),
            (m.peak_altitude_km(Line::O630), g.peak("ver_6300")),
        ],
    }
}

fn rows() -> Vec<Row> {
    [1.0, 2.0, 5.0].into_iter().map(compare).collect()
}

#[allow(clippy::print_stderr, reason = "the comparison table, for the record of a run")]
fn print(rows: &[Row]) {
    eprintln!(
        "E0 keV | 427.8 col ours/GLOW | 557.7/427.8 ours/GLOW | 630.0/427.8 ours/GLOW (bg-sub) | peaks 427.8, 557.7, 630.0 ours/GLOW km"
    );
    for r in rows {
        eprintln!(
            "{} | {:.4e} / {:.4e} | {:.3} / {:.3} | {:.3} / {:.3} ({:.3}) | {}/{}, {}/{}, {}/{}",
            r.e0,
            r.col_428.0,
            r.col_428.1,
            r.ratio_558.0,
            r.ratio_558.1,
            r.ratio_630.0,
            r.ratio_630.1,
            r.ratio_630_no_background,
            r.peaks[0].0,
            r.peaks[0].1,
            r.peaks[1].0,
            r.peaks[1].1,
            r.peaks[2].0,
            r.peaks[2].1
        );
    }
}

#[test]
fn the_green_and_blue_lines_still_agree_with_glow() {
    let rows = rows();
    print(&rows);
    for r in &rows {
        let within = |(a, b): (f64, f64), tol: f64| (a / b - 1.0).abs() <= tol;
        assert!(within(r.col_428, 0.30), "{} keV: 427.8 nm column per erg {:?}", r.e0, r.col_428);
        assert!(within(r.ratio_558, 0.30), "{} keV: 557.7/427.8 {:?}", r.e0, r.ratio_558);
        for (k, (a, b)) in r.peaks[..2].iter().enumerate() {
            assert!((a - b).abs() <= 5.0, "{} keV: peak {k}: ours {a} km, GLOW {b} km", r.e0);
        }
    }
}

#[test]
fn the_red_line_column_agrees_with_glow() {
    for r in rows() {
        let (ours, glow) = r.ratio_630;
        assert!((ours / glow - 1.0).abs() <= 0.5, "{} keV: 630.0/427.8 ours {ours}, GLOW {glow}", r.e0);
        let bare = r.ratio_630_no_background;
        assert!(
            (ours / bare - 1.0).abs() <= 0.5,
            "{} keV: 630.0/427.8 ours {ours}, GLOW less background {bare}",
            r.e0
        );
    }
}

#[test]
fn the_red_line_sources_are_those_that_matter_in_glow() {
    // Not a tolerance of the issue: a check that the budget has the right shape. GLOW's
    // column fractions of O(¹D) production (summary.txt; 1/2/5 keV): electron impact on
    // O 0.55/0.47/0.31, O₂⁺ recombination 0.14/0.13/0.20, N(²D) + O₂ 0.10/0.15/0.19,
    // the O(¹S) cascade 0.08/0.10/0.10. Ours must rank electron impact first at 1 and 2
    // keV and have each of the other three within a factor of two of GLOW's.
    let glow = [[0.545, 0.139, 0.104, 0.082], [0.467, 0.131, 0.150, 0.095], [0.313, 0.199, 0.192, 0.097]];
    let sources = [
        O1dSource::ElectronImpact,
        O1dSource::DissociativeRecombination,
        O1dSource::NitrogenWithO2,
        O1dSource::O1sCascade,
    ];
    for (e0, g) in [1.0, 2.0, 5.0].into_iter().zip(glow) {
        let m = ours(e0);
        let z = m.altitudes_km();
        let column = |s: O1dSource| trapezoid(z, m.o1d_production(s));
        let total: f64 = O1dSource::ALL.iter().map(|&s| column(s)).sum();
        let share: Vec<f64> = sources.iter().map(|&s| column(s) / total).collect();
        for (k, (&ours, &glow)) in share.iter().zip(&g).enumerate() {
            assert!(ours > 0.5 * glow && ours < 2.0 * glow, "{e0} keV source {k}: {ours} vs GLOW {glow}");
        }
        if e0 < 3.0 {
            assert!(share[0] > share[1] && share[0] > share[2], "{e0} keV: {share:?}");
        }
    }
}

/// The last tolerance, the 630.0 nm peak within 15 km of GLOW's, is not met,
/// and this test says so rather than loosening it: ours peaks at 223 km for each of
/// 1, 2, 5 keV against GLOW's 197, 197, 263 km (measured 2026-12-03). Our profiles are
/// flat-topped (within 2 % of their peak from 210 to 240 km), so the argmax is fragile.
/// What a review of 2026-12-03 traced (a Python copy of `degradation.rs` reproducing
/// its O(¹D) yield to 1 %, and GLOW re-run at our atmosphere's conditions: same date,
/// 69.6° N, F10.7 = 150, Ap = 15):
/// - The main cause is ours: the local energy degradation (`degradation.rs`, "Known
///   limit") makes the O(¹D) yield per ion pair rise with altitude above 200 km where
///   GLOW's transported yield falls; with GLOW's yield shape our peak would be at
///   213/206/205 km.
/// - GLOW's 197 km is partly its own: it computes the electron density only below
///   200 km (kchem = 4) and takes IRI's night F region above, so its O₂⁺ recombination
///   source drops by 10x at 205 km; holding its recombination-to-ionisation ratio above
///   197 km moves its peaks to 221/213/205 km in the matched run.
/// - GLOW's 5 keV peak at 263 km is its F-region background (17.7 R peaking at 272 km
///   with no precipitation); our model has no background ionosphere.
/// - Not the atmosphere: GLOW at our conditions still peaks at 197/197 km for 1 and
///   2 keV (an earlier note here blamed our hotter atmosphere; the matched run refutes
///   it).
#[test]
#[ignore = "issue 20's 15 km criterion for the 630.0 nm peak is not met (ours 223 km, GLOW 197/197/263 km)"]
fn red_line_peaks() {
    for r in rows() {
        let (ours, glow) = r.peaks[2];
        assert!((ours - glow).abs() <= 15.0, "{} keV: 630.0 nm peak ours {ours} km, GLOW {glow} km", r.e0);
    }
}
