//! `export blackbody` writes the paper's Fig 1 table, matching colour-science;
//! `export atmosphere` the aurora's model atmosphere.

use crate::{fails, ok, png_size};

#[test]
fn csv_matches_the_colour_science_reference() {
    let dir = tempfile::tempdir().unwrap();
    ok(
        dir.path(),
        &[
            "export",
            "blackbody",
            "--min-k",
            "1000",
            "--max-k",
            "10000",
            "--step-k",
            "100",
            "--format",
            "csv",
            "--out",
            "bb.csv",
        ],
    );
    let ours = std::fs::read_to_string(dir.path().join("bb.csv")).unwrap();
    let reference = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/data/blackbody_colour_science.csv"
    ))
    .unwrap();
    let parse = |t: &str| -> Vec<Vec<f64>> {
        t.lines().skip(1).map(|l| l.split(',').map(|f| f.parse().unwrap()).collect()).collect()
    };
    assert_eq!(ours.lines().next(), Some("temperature_k,x,y,r,g,b"));
    let (a, b) = (parse(&ours), parse(&reference));
    assert_eq!(a.len(), b.len());
    for (ra, rb) in a.iter().zip(&b) {
        assert_eq!(ra[0], rb[0]);
        // Tolerances: 1e-4 in x, y; 2e-3 in linear r, g, b.
        for k in 1..3 {
            assert!((ra[k] - rb[k]).abs() < 1e-4, "{ra:?} vs {rb:?}");
        }
        for k in 3..6 {
            assert!((ra[k] - rb[k]).abs() < 2e-3, "{ra:?} vs {rb:?}");
        }
    }
}

#[test]
fn png_strip_has_one_pixel_per_temperature() {
    let dir = tempfile::tempdir().unwrap();
    ok(
        dir.path(),
        &[
            "export",
            "blackbody",
            "--min-k",
            "1000",
            "--max-k",
            "2000",
            "--step-k",
            "10",
            "--format",
            "png",
            "--out",
            "strip.png",
        ],
    );
    assert_eq!(png_size(&dir.path().join("strip.png")), (101, 1));
}

#[test]
fn bad_ranges_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let e =
        fails(dir.path(), &["export", "blackbody", "--min-k", "5000", "--max-k", "100", "--out", "x.csv"]);
    assert!(e.contains("--max-k 100 is out of range"), "{e}");
    let e = fails(dir.path(), &["export", "blackbody", "--step-k", "0", "--out", "x.csv"]);
    assert!(e.contains("--step-k 0"), "{e}");
    assert!(!dir.path().join("x.csv").exists());
}

#[test]
fn the_atmosphere_table_has_its_header_and_421_altitudes() {
    let dir = tempfile::tempdir().unwrap();
    ok(dir.path(), &["export", "atmosphere", "--format", "csv", "--out", "out/air.csv"]);
    let text = std::fs::read_to_string(dir.path().join("out/air.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("altitude_km,n_o,n_n2,n_o2,temperature_k"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|f| f.parse().unwrap()).collect()).collect();
    assert_eq!(rows.len(), 421);
    assert_eq!((rows[0][0], rows[420][0]), (80.0, 500.0));
    assert!(rows.iter().all(|r| r.len() == 5 && r[1..].iter().all(|&v| v > 0.0)));
    // A usage error: clap's exit code 2, naming the value and the valid ones.
    let out = crate::run(dir.path(), &["export", "atmosphere", "--format", "xml", "--out", "a.csv"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("'xml'") && err.contains("possible values: csv"), "{err}");
}

#[test]
fn the_aurora_profile_has_the_issues_header_and_its_green_peak() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "export",
        "aurora-profile",
        "--energy-kev",
        "2",
        "--spectrum",
        "maxwellian",
        "--flux-erg",
        "1",
        "--format",
        "csv",
        "--out",
        "p/profile.csv",
        "--red-line",
        "p/red.csv",
    ];
    ok(dir.path(), &args);
    let text = std::fs::read_to_string(dir.path().join("p/profile.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("altitude_km,v_391_4,v_427_8,v_557_7,v_630_0,v_670_5"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|f| f.parse().unwrap()).collect()).collect();
    assert_eq!(rows.len(), 421);
    assert_eq!((rows[0][0], rows[420][0]), (80.0, 500.0));
    let peak = rows.iter().max_by(|a, b| a[3].total_cmp(&b[3])).unwrap()[0];
    assert!((100.0..=130.0).contains(&peak), "557.7 nm peak at {peak} km");
    // The red line's budget: its sources, and the same 630.0 nm as the profile.
    let red = std::fs::read_to_string(dir.path().join("p/red.csv")).unwrap();
    let mut red_lines = red.lines();
    let header = red_lines.next().unwrap();
    assert!(
        header.starts_with("altitude_km,electron_density_cm3,p_electron_impact,p_o2p_recombination"),
        "{header}"
    );
    assert!(header.ends_with(",radiated_share,v_630_0"), "{header}");
    let last: Vec<f64> = red_lines.clone().map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect();
    assert_eq!(last.len(), 421);
    for (a, row) in last.iter().zip(&rows) {
        assert!((a - row[4]).abs() <= 1e-5 * row[4].abs().max(1e-30), "{a} vs {}", row[4]);
    }
    // Out-of-range energy: the flag, the value and the range.
    let err = fails(dir.path(), &["export", "aurora-profile", "--energy-kev", "0.01", "--out", "x.csv"]);
    assert!(err.contains("--energy-kev") && err.contains("0.01") && err.contains("1000"), "{err}");
    assert!(!dir.path().join("x.csv").exists());
}

#[test]
fn the_aurora_profile_reads_the_air_of_other_conditions() {
    // `--air DIR`: the three tables of tests/data/air/tromso (F10.7 = 150) give another
    // profile than the shipped air (F10.7 = 100): the warmer thermosphere lifts the red
    // line (measured 2026-12-04: 217 against 208 km at 1 keV).
    let dir = tempfile::tempdir().unwrap();
    let air = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/air/tromso");
    let base = ["export", "aurora-profile", "--energy-kev", "1", "--out"];
    let shipped = ok(dir.path(), &[&base[..], &["shipped.csv"]].concat());
    let other = ok(dir.path(), &[&base[..], &["tromso.csv", "--air", air]].concat());
    let peak = |summary: &str| -> f64 {
        let at = summary.find("630.0 nm").unwrap();
        let rest = &summary[at..];
        let p = rest.find("peak at ").unwrap() + "peak at ".len();
        rest[p..].split(' ').next().unwrap().parse().unwrap()
    };
    assert!(peak(&other) > peak(&shipped), "{shipped}\n{other}");
    let (a, b) = (
        std::fs::read_to_string(dir.path().join("shipped.csv")).unwrap(),
        std::fs::read_to_string(dir.path().join("tromso.csv")).unwrap(),
    );
    assert_ne!(a, b);
    // A missing table names the file; a bad one its file and line; nothing is written.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let err = fails(dir.path(), &[&base[..], &["x.csv", "--air", empty.to_str().unwrap()]].concat());
    assert!(err.contains("--air") && err.contains("atmosphere_msis21.csv"), "{err}");
    let bad = dir.path().join("bad");
    std::fs::create_dir(&bad).unwrap();
    for name in ["atmosphere_msis21.csv", "ionosphere_iri90.csv"] {
        std::fs::copy(format!("{air}/{name}"), bad.join(name)).unwrap();
    }
    std::fs::write(bad.join("atmosphere_msis21_minor.csv"), "altitude_km,n_n,n_no\n80,1,1\n81,x,1\n")
        .unwrap();
    let err = fails(dir.path(), &[&base[..], &["x.csv", "--air", bad.to_str().unwrap()]].concat());
    assert!(err.contains("atmosphere_msis21_minor.csv") && err.contains("line 3"), "{err}");
    assert!(!dir.path().join("x.csv").exists());
}

/// `--air` tables whose values parse but are not air are refused at their file and
/// line, never written as NaN profiles or a panic: a NaN altitude in the first row or
/// mid-table, densities and temperatures of 1e300 and 1e-300, negative altitudes; a
/// FIFO in place of a table is refused without waiting for a writer.
#[test]
fn air_tables_that_are_not_air_are_refused_at_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let air = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/air/tromso");
    let copy = |case: &str, file: &str, text: &str| {
        let d = dir.path().join(case);
        std::fs::create_dir(&d).unwrap();
        for name in ["atmosphere_msis21.csv", "atmosphere_msis21_minor.csv", "ionosphere_iri90.csv"] {
            std::fs::copy(format!("{air}/{name}"), d.join(name)).unwrap();
        }
        std::fs::write(d.join(file), text).unwrap();
        d.to_string_lossy().into_owned()
    };
    let neutral = "altitude_km,n_o,n_n2,n_o2,temperature_k\n";
    let cases = [
        (
            "minor-nan-first",
            "atmosphere_msis21_minor.csv",
            "altitude_km,n_n,n_no\nNaN,1,1\n500,1,1\n".to_string(),
            "line 2",
        ),
        (
            "minor-nan-mid",
            "atmosphere_msis21_minor.csv",
            "altitude_km,n_n,n_no\n80,1,1\nNaN,1,1\n500,1,1\n".into(),
            "line 3",
        ),
        (
            "huge",
            "atmosphere_msis21.csv",
            format!("{neutral}80,1e300,1e20,1e19,200\n500,1e14,1e12,1e10,800\n"),
            "line 2",
        ),
        (
            "tiny",
            "atmosphere_msis21.csv",
            format!("{neutral}80,1e16,1e-300,1e19,200\n500,1e14,1e12,1e10,800\n"),
            "line 2",
        ),
        (
            "hot",
            "atmosphere_msis21.csv",
            format!("{neutral}80,1e16,1e20,1e19,200\n500,1e14,1e12,1e10,1e300\n"),
            "line 3",
        ),
        (
            "below",
            "atmosphere_msis21.csv",
            format!("{neutral}-900,1e16,1e20,1e19,200\n-800,1e14,1e12,1e10,800\n"),
            "line 2",
        ),
    ];
    for (case, file, text, line) in cases {
        let d = copy(case, file, &text);
        let out = format!("{case}.csv");
        let err =
            fails(dir.path(), &["export", "aurora-profile", "--energy-kev", "1", "--out", &out, "--air", &d]);
        assert!(err.contains(&format!("{file}: {line}:")) && err.contains("out of range"), "{case}: {err}");
        assert!(!dir.path().join(&out).exists(), "{case}: a profile was written");
    }
    let d = copy("fifo", "ionosphere_iri90.csv", "");
    std::fs::remove_file(format!("{d}/ionosphere_iri90.csv")).unwrap();
    let made =
        std::process::Command::new("mkfifo").arg(format!("{d}/ionosphere_iri90.csv")).status().unwrap();
    assert!(made.success());
    let err =
        fails(dir.path(), &["export", "aurora-profile", "--energy-kev", "1", "--out", "f.csv", "--air", &d]);
    assert!(err.contains("ionosphere_iri90.csv") && err.contains("not a regular file"), "{err}");
}
