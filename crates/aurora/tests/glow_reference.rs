//! The physical mode's column model against an independent 1-D auroral model:
//! NCAR GLOW v0.981, run by `tools/glow-ref` (our driver; GLOW's source is not in the
//! repository) for Maxwellian electrons of E0 = 1, 2, 5 keV at 1 erg cm⁻² s⁻¹, 65° N,
//! winter local midnight, F10.7 = 100, Ap = 10. Its profiles are committed in
//! `tests/data/glow/` (provenance in its README).
//!
//! This is model against model at the same conditions: ours runs over its own NRLMSIS
//! 2.1 and IRI-90 tables, made for exactly these conditions (`crates/aurora/data/`),
//! GLOW over its bundled NRLMSISE-00 and IRI-90. The tolerances are the issue's own
//! ("Done when"): 427.8 and 557.7 nm peaks within 5 km, 557.7/427.8 within ±30 %, the
//! 427.8 column per erg within ±30 %, the 630.0/427.8 column ratio within ±50 %, the
//! 630.0 nm peak within 15 km. Nothing in our model is fitted to these numbers; they are
//! only compared.
//!
//! GLOW's columns include its night background (IRI's F region gives 17.7 R of 630.0 nm
//! without precipitation, peaking at 272 km). Ours has one too (`NightIonosphere`), so
//! what a photometer sees (`ColumnModel::seen_from_the_ground`) is compared with GLOW's
//! full output, and the aurora's part (`volume_emission`, what the renderer draws) with
//! GLOW's output less its no-precipitation run. `tests/data/glow/matched/` holds GLOW
//! run at other conditions (69.6° N 19° E, 2024-01-15 22 UT, F10.7 = 150, Ap = 15), ours
//! there reads the tables of `tests/data/air/tromso/`: the night glow and the 5 keV red
//! peak, which depend most on the conditions, are compared there as well.
//! `tests/data/glow/ne250/` holds GLOW rebuilt to solve its ion balance up to 250 km
//! instead of 200 (the conditions otherwise): the red peak is compared there.

use phenomena_aurora::atmosphere::{Atmosphere, MinorSpecies, NightIonosphere};
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

fn ours(air: &Atmosphere, e0: f64) -> ColumnModel {
    ColumnModel::new(
        air,
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
    /// The aurora's part: ours without the night glow, GLOW less its no-precipitation run.
    ratio_630_aurora: (f64, f64),
    peaks: [(f64, f64); 3],
    peak_630_aurora: (f64, f64),
}

fn compare(dir: &str, air: &Atmosphere, e0: f64) -> Row {
    let m = ours(air, e0);
    let g = Glow::load(&format!("{dir}glow_E{e0}keV.csv"));
    let bg = Glow::load(&format!("{dir}glow_noprecip.csv"));
    let c = |l: Line| m.seen_column_photons_cm2_s(l);
    let (g428, g558, g630) = (g.column("ver_4278"), g.column("ver_5577"), g.column("ver_6300"));
    let aurora_630: Vec<f64> = g.col("ver_6300").iter().zip(bg.col("ver_6300")).map(|(a, b)| a - b).collect();
    Row {
        e0,
        col_428: (c(Line::N2p428), g428),
        ratio_558: (c(Line::O557) / c(Line::N2p428), g558 / g428),
        ratio_630: (c(Line::O630) / c(Line::N2p428), g630 / g428),
        ratio_630_aurora: (
            m.column_photons_cm2_s(Line::O630) / m.column_photons_cm2_s(Line::N2p428),
            (g630 - bg.column("ver_6300")) / g428,
        ),
        peaks: [
            (m.seen_peak_altitude_km(Line::N2p428), g.peak("ver_4278")),
            (m.seen_peak_altitude_km(Line::O557), g.peak("ver_5577")),
            (m.seen_peak_altitude_km(Line::O630), g.peak("ver_6300")),
        ],
        peak_630_aurora: (m.peak_altitude_km(Line::O630), peak(&g.z_km, &aurora_630)),
    }
}

fn rows() -> Vec<Row> {
    [1.0, 2.0, 5.0].into_iter().map(|e0| compare("", Atmosphere::msis21(), e0)).collect()
}

#[allow(clippy::print_stderr, reason = "the comparison table, for the record of a run")]
fn print(rows: &[Row]) {
    eprintln!(
        "E0 keV | 427.8 col ours/GLOW | 557.7/427.8 ours/GLOW | 630.0/427.8 ours/GLOW (aurora's part) | peaks 427.8, 557.7, 630.0 (aurora's part) ours/GLOW km"
    );
    for r in rows {
        eprintln!(
            "{} | {:.4e} / {:.4e} | {:.3} / {:.3} | {:.3} / {:.3} ({:.3} / {:.3}) | {}/{}, {}/{}, {}/{} ({}/{})",
            r.e0,
            r.col_428.0,
            r.col_428.1,
            r.ratio_558.0,
            r.ratio_558.1,
            r.ratio_630.0,
            r.ratio_630.1,
            r.ratio_630_aurora.0,
            r.ratio_630_aurora.1,
            r.peaks[0].0,
            r.peaks[0].1,
            r.peaks[1].0,
            r.peaks[1].1,
            r.peaks[2].0,
            r.peaks[2].1,
            r.peak_630_aurora.0,
            r.peak_630_aurora.1
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
        let (ours, bare) = r.ratio_630_aurora;
        assert!(
            (ours / bare - 1.0).abs() <= 0.5,
            "{} keV: 630.0/427.8 of the aurora alone: ours {ours}, GLOW less background {bare}",
            r.e0
        );
    }
}

/// GLOW's own neutral air (its NRLMSISE-00 O, N₂, O₂, temperature and NOEM's NO and
/// N(⁴S), from `glow_noprecip.csv`), log-interpolated to our 1 km grid, in our night
/// ionosphere (IRI-90 at the same conditions, as GLOW's): our model in GLOW's air.
fn glow_air() -> Atmosphere {
    let g = Glow::load("glow_noprecip.csv");
    let at = |name: &str, z: f64| -> f64 {
        let v = g.col(name);
        let k = g.z_km.partition_point(|&x| x <= z).clamp(1, g.z_km.len() - 1) - 1;
        let t = (z - g.z_km[k]) / (g.z_km[k + 1] - g.z_km[k]);
        if v[k] > 0.0 && v[k + 1] > 0.0 {
            v[k] * (v[k + 1] / v[k]).powf(t)
        } else {
            v[k] + (v[k + 1] - v[k]) * t
        }
    };
    let (mut main, mut minor) =
        (String::from("altitude_km,n_o,n_n2,n_o2,temperature_k\n"), String::from("altitude_km,n_n,n_no\n"));
    for z in 80..=500 {
        let z = f64::from(z);
        // cm⁻³ -> m⁻³: 1e6.
        let m3 = |name: &str| at(name, z) * 1e6;
        main.push_str(&format!(
            "{z},{:e},{:e},{:e},{}\n",
            m3("O_cm3"),
            m3("N2_cm3"),
            m3("O2_cm3"),
            at("Tn_K", z)
        ));
        minor.push_str(&format!("{z},{:e},{:e}\n", m3("N4S_cm3"), m3("NO_cm3")));
    }
    Atmosphere::from_csv(&main)
        .expect("GLOW's air makes a valid table")
        .with_minor_species(MinorSpecies::from_csv(&minor).expect("GLOW's NO and N make a valid table"))
        .with_night_ionosphere(NightIonosphere::iri90().clone())
}

#[test]
fn the_red_line_sources_are_those_that_matter_in_glow() {
    // Not a tolerance of the issue: a check that the budget has the right shape. GLOW's
    // column fractions of O(¹D) production (summary.txt; 1/2/5 keV): electron impact on
    // O 0.55/0.47/0.31, O₂⁺ recombination 0.14/0.13/0.20, N(²D) + O₂ 0.10/0.15/0.19,
    // the O(¹S) cascade 0.08/0.10/0.10. In GLOW's own air ours must have each within a
    // factor of two of GLOW's (measured 2026-12-04: 0.90-1.17 of GLOW's, every source
    // and energy), and in both airs rank electron impact first at 1 and 2 keV.
    // In our own air the recombination share is 1.7-2.3x GLOW's: NRLMSIS 2.1's NO is
    // 3x below NOEM's (GLOW's) at 110 km and 5-7x at 120-170 km, and NO takes O₂⁺ away
    // from recombination (O₂⁺ + NO -> NO⁺ + O₂); with NOEM's NO in our air the share
    // falls to 1.2-1.3x. Air, not chemistry: so the shape is checked in GLOW's air.
    let glow = [[0.545, 0.139, 0.104, 0.082], [0.467, 0.131, 0.150, 0.095], [0.313, 0.199, 0.192, 0.097]];
    let sources = [
        O1dSource::ElectronImpact,
        O1dSource::DissociativeRecombination,
        O1dSource::NitrogenWithO2,
        O1dSource::O1sCascade,
    ];
    let shares = |air: &Atmosphere, e0: f64| -> Vec<f64> {
        let m = ours(air, e0);
        let z = m.altitudes_km();
        let column = |s: O1dSource| trapezoid(z, m.o1d_production(s));
        let total: f64 = O1dSource::ALL.iter().map(|&s| column(s)).sum();
        sources.iter().map(|&s| column(s) / total).collect()
    };
    let in_glow_air = glow_air();
    for (e0, g) in [1.0, 2.0, 5.0].into_iter().zip(glow) {
        let share = shares(&in_glow_air, e0);
        for (k, (&ours, &glow)) in share.iter().zip(&g).enumerate() {
            assert!(ours > 0.5 * glow && ours < 2.0 * glow, "{e0} keV source {k}: {ours} vs GLOW {glow}");
        }
        if e0 < 3.0 {
            for share in [share, shares(Atmosphere::msis21(), e0)] {
                assert!(share[0] > share[1] && share[0] > share[2], "{e0} keV: {share:?}");
            }
        }
    }
}

/// The last tolerance: the 630.0 nm peak within 15 km of GLOW's, as seen from the
/// ground and for the aurora's part. Measured 2026-12-04: ours 208 / 206 / 261 km for 1 /
/// 2 / 5 keV against GLOW's 197 / 197 / 263 km; the aurora's part 207 / 204 / 201 km
/// against 197. (Stock GLOW's 1-2 keV peak sits where it stops solving the ion balance,
/// 200 km; see the test after this one.)
#[test]
fn red_line_peaks() {
    for r in rows() {
        let (ours, glow) = r.peaks[2];
        assert!((ours - glow).abs() <= 15.0, "{} keV: 630.0 nm peak ours {ours} km, GLOW {glow} km", r.e0);
        let (ours, glow) = r.peak_630_aurora;
        assert!(
            (ours - glow).abs() <= 15.0,
            "{} keV: aurora's 630.0 nm peak ours {ours} km, GLOW {glow} km",
            r.e0
        );
    }
}

#[test]
fn the_red_line_peaks_where_glow_puts_it_when_glow_solves_the_ion_balance_higher_up() {
    // GLOW's stock run stops computing the electron density at 200 km (kchem = 4) and
    // takes IRI-90's above, so its aurora's O₂⁺ recombination ends there and its red
    // peak sits at the switch: 197 km. Rebuilt with that switch at 250 km
    // (`tools/glow-ref/build.sh` with GLOW_NE_TOP_KM=250; `tests/data/glow/ne250/`),
    // nothing else changed, GLOW peaks at 213 km for 1 and 2 keV; at 300 km too (not
    // committed, same build), so 213 km is GLOW's own answer once its ion balance
    // covers the red layer. The issue asks for that balance ("an electron density from
    // the balance of ion production and recombination"); compared here with the
    // issue's tolerances: peak within 15 km, 630.0/427.8 within ±50 %, seen from the
    // ground and for the aurora's part. (5 keV's peak is the night F region's, IRI's
    // above the switch in both builds: `red_line_peaks` compares it.)
    for e0 in [1.0, 2.0] {
        let r = compare("ne250/", Atmosphere::msis21(), e0);
        print(std::slice::from_ref(&r));
        let (ours, glow) = r.peaks[2];
        assert!((ours - glow).abs() <= 15.0, "{e0} keV: 630.0 nm peak ours {ours} km, GLOW {glow} km");
        let (ours, glow) = r.peak_630_aurora;
        assert!(
            (ours - glow).abs() <= 15.0,
            "{e0} keV: aurora's 630.0 nm peak ours {ours} km, GLOW {glow} km"
        );
        let (ours, glow) = r.ratio_630;
        assert!((ours / glow - 1.0).abs() <= 0.5, "{e0} keV: 630.0/427.8 ours {ours}, GLOW {glow}");
    }
}

/// The column without precipitation: the night sky's own glow.
fn night(air: &Atmosphere) -> ColumnModel {
    ColumnModel::new(
        air,
        &Precipitation { spectrum: Spectrum::Maxwellian, energy_kev: 1.0, flux_erg_cm2_s: 0.0 },
        &Yields::default(),
    )
}

#[test]
fn the_night_glow_agrees_with_glow() {
    // GLOW's night 630.0 nm glow without precipitation (`glow_noprecip.csv`): 17.7 R
    // peaking at 272 km. The tolerances for the red line (column within ±50 %,
    // peak within 15 km); and with no aurora the renderer draws nothing.
    let bg = Glow::load("glow_noprecip.csv");
    let none = night(Atmosphere::msis21());
    let ours = none.seen_column_photons_cm2_s(Line::O630);
    let glow = bg.column("ver_6300");
    assert!((ours / glow - 1.0).abs() <= 0.5, "night glow: ours {ours}, GLOW {glow}");
    let (peak, glow_peak) = (none.seen_peak_altitude_km(Line::O630), bg.peak("ver_6300"));
    assert!((peak - glow_peak).abs() <= 15.0, "night glow peak: ours {peak} km, GLOW {glow_peak} km");
    assert_eq!(none.column_photons_cm2_s(Line::O630), 0.0, "no aurora, nothing for the renderer");
}

/// The tables of `tests/data/air/tromso/`, read as `export aurora-profile --air` reads them.
fn tromso() -> Atmosphere {
    let dir = format!("{}/../../tests/data/air/tromso", env!("CARGO_MANIFEST_DIR"));
    let read = |name: &str| {
        std::fs::read_to_string(format!("{dir}/{name}")).unwrap_or_else(|e| panic!("{dir}/{name}: {e}"))
    };
    Atmosphere::from_tables(
        &read("atmosphere_msis21.csv"),
        &read("atmosphere_msis21_minor.csv"),
        &read("ionosphere_iri90.csv"),
    )
    .expect("the Tromso tables are valid")
}

#[test]
fn at_other_conditions_the_night_glow_and_the_hard_aurora_agree_with_glow_there() {
    // GLOW run at 69.6° N 19° E, 2024-01-15 22 UT, F10.7 = 150, Ap = 15
    // (`tests/data/glow/matched/`), ours over the tables of the same conditions: the
    // night glow (GLOW 27.75 R at 290 km; ours measured 26 R at 295 km) and the 5 keV
    // aurora whose red peak is the night F region's (GLOW 290 km, ours 287), with the
    // issue's tolerances; the green and blue lines' for every energy. Not the 1-2 keV
    // red peak: GLOW's stays at 197 km, pinned where it stops solving the ion balance,
    // while ours rises with the warmer thermosphere to 217 / 215 km (208 / 206 at the
    // issue's conditions).
    let air = tromso();
    let bg = Glow::load("matched/glow_noprecip.csv");
    let none = night(&air);
    let ours = none.seen_column_photons_cm2_s(Line::O630);
    let glow = bg.column("ver_6300");
    assert!((ours / glow - 1.0).abs() <= 0.5, "night glow: ours {ours}, GLOW {glow}");
    assert!((none.seen_peak_altitude_km(Line::O630) - bg.peak("ver_6300")).abs() <= 15.0);
    for e0 in [1.0, 2.0, 5.0] {
        let r = compare("matched/", &air, e0);
        print(std::slice::from_ref(&r));
        let within = |(a, b): (f64, f64), tol: f64| (a / b - 1.0).abs() <= tol;
        assert!(within(r.col_428, 0.30), "{e0} keV: 427.8 nm column per erg {:?}", r.col_428);
        assert!(within(r.ratio_558, 0.30), "{e0} keV: 557.7/427.8 {:?}", r.ratio_558);
        assert!(within(r.ratio_630, 0.50), "{e0} keV: 630.0/427.8 {:?}", r.ratio_630);
        for (k, (a, b)) in r.peaks[..2].iter().enumerate() {
            assert!((a - b).abs() <= 5.0, "{e0} keV: peak {k}: ours {a} km, GLOW {b} km");
        }
        if e0 == 5.0 {
            let (ours, glow) = r.peaks[2];
            assert!((ours - glow).abs() <= 15.0, "5 keV: 630.0 nm peak ours {ours} km, GLOW {glow} km");
        }
    }
}
