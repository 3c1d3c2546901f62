//! The aurora's sky view through the CLI: each thesis scene renders at a small size,
//! EXR frames carry the five line images as extra channels, and one or two threads
//! write the same bytes.

use crate::{fails, ok, write};

/// Scene `scenes/NAME` with its particle count and frames cut down, at 160×90.
fn small_copy(dir: &std::path::Path, name: &str) -> String {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let text = std::fs::read_to_string(root.join(name)).unwrap();
    let mut doc: toml::Table = text.parse().unwrap();
    let scene = doc.get_mut("scene").unwrap().as_table_mut().unwrap();
    scene.insert("width".into(), 160.into());
    scene.insert("height".into(), 90.into());
    let aurora = doc.get_mut("aurora").unwrap().as_table_mut().unwrap();
    let motion = aurora.entry("motion").or_insert(toml::Value::Table(Default::default()));
    motion.as_table_mut().unwrap().insert("particles".into(), 6000.into());
    write(dir, name, &doc.to_string())
}

#[test]
fn every_thesis_scene_renders_a_sky_with_light_in_it() {
    let dir = tempfile::tempdir().unwrap();
    for k in 1..=5 {
        let name = format!("aurora-scene{k}.toml");
        let scene = small_copy(dir.path(), &name);
        let out = format!("s{k}");
        ok(dir.path(), &["render", &scene, "--out", &out, "--frames", "2"]);
        let png = image::open(dir.path().join(&out).join("frame_00002.png")).unwrap().to_rgb8();
        assert_eq!(png.dimensions(), (160, 90));
        let lit = png.pixels().filter(|p| p.0.iter().any(|&c| c > 8)).count();
        assert!(lit > 100, "{name}: only {lit} lit pixels");
        // Aurora light is mostly green in the physical mode: summed above the night sky
        // around it (each channel's median, the airglow's level), green leads.
        let median = |c: usize| {
            let mut v: Vec<u8> = png.pixels().map(|p| p.0[c]).collect();
            v.sort_unstable();
            v[v.len() / 2]
        };
        let sum = |c: usize| png.pixels().map(|p| u64::from(p.0[c].saturating_sub(median(c)))).sum::<u64>();
        assert!(sum(1) > sum(0) && sum(1) > sum(2), "{name}: rgb sums {} {} {}", sum(0), sum(1), sum(2));
    }
}

#[test]
fn exr_frames_carry_the_five_line_images() {
    use exr::prelude::*;
    let dir = tempfile::tempdir().unwrap();
    let scene = small_copy(dir.path(), "aurora-scene1.toml");
    ok(dir.path(), &["render", &scene, "--out", "e", "--frames", "1", "--format", "exr"]);
    let image = read_all_flat_layers_from_file(dir.path().join("e/frame_00001.exr")).unwrap();
    let names: Vec<String> =
        image.layer_data[0].channel_data.list.iter().map(|c| c.name.to_string()).collect();
    for want in [
        "R",
        "G",
        "B",
        "aurora_391_4.Y",
        "aurora_427_8.Y",
        "aurora_557_7.Y",
        "aurora_630_0.Y",
        "aurora_670_5.Y",
    ] {
        assert!(names.iter().any(|n| n == want), "{want} missing from {names:?}");
    }
    // The line images are in rayleighs: 391.4/427.8 is the N2⁺ branching ratio 3.25 in
    // every pixel's expectation; summed over the image, within sampling noise.
    let total = |name: &str| -> f64 {
        let c = image.layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
        match &c.sample_data {
            FlatSamples::F32(v) => v.iter().map(|&x| f64::from(x)).sum(),
            _ => panic!("{name} is not f32"),
        }
    };
    let ratio = total("aurora_391_4.Y") / total("aurora_427_8.Y");
    // Both lines share one altitude profile and the same number of points per particle
    // (2 at least), drawn independently: the ratio of the sums scatters by a few per cent.
    assert!((ratio / 3.25 - 1.0).abs() < 0.1, "391.4/427.8 = {ratio}");
}

#[test]
fn sky_frames_are_identical_for_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let scene = small_copy(dir.path(), "aurora-scene2.toml");
    ok(dir.path(), &["render", &scene, "--out", "t1", "--threads", "1", "--frames", "3"]);
    ok(dir.path(), &["render", &scene, "--out", "t2", "--threads", "2", "--frames", "3"]);
    let a = std::fs::read(dir.path().join("t1/frame_00003.png")).unwrap();
    let b = std::fs::read(dir.path().join("t2/frame_00003.png")).unwrap();
    assert!(a == b, "sky frame differs between 1 and 2 threads");
}

#[test]
fn bad_sky_settings_name_the_field_and_the_range() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "bad.toml",
        "[scene]\nframes = 2\nwidth = 64\nheight = 36\n[aurora.motion]\nparticles = 2000\n[render.sky]\npoints_per_particle = 1\n[render.sky.precipitation]\nenergy_kev = 5000.0\n",
    );
    let err = fails(dir.path(), &["render", &scene, "--out", "o"]);
    assert!(
        err.contains("bad.toml:8:23: render.sky.points_per_particle = 1: expected an integer in [5, 10000]"),
        "{err}"
    );
    assert!(
        err.contains(
            "bad.toml:10:14: render.sky.precipitation.energy_kev = 5000: expected a value in [0.1, 1000]"
        ),
        "{err}"
    );
    // Unknown keys are refused with their place in the file.
    let scene =
        write(dir.path(), "typo.toml", "[scene]\nframes = 2\n[aurora]\n[render.sky]\nafterglo = true\n");
    let err = fails(dir.path(), &["render", &scene, "--out", "o"]);
    assert!(err.contains("typo.toml:5:1: unknown field `afterglo`"), "{err}");
}

/// The shape export of every thesis scene with splits or merges, at the
/// frames before and after they happen, is a consistent table: every `next` names a
/// point of the same sheet that exists.
#[test]
fn shape_exports_after_splits_and_merges_are_consistent() {
    let dir = tempfile::tempdir().unwrap();
    for k in [2, 3, 4, 5] {
        let scene = small_copy(dir.path(), &format!("aurora-scene{k}.toml"));
        for frame in ["0", "1"] {
            let out = format!("shape{k}-{frame}.csv");
            ok(dir.path(), &["export", "shape", &scene, "--frame", frame, "--out", &out]);
            let text = std::fs::read_to_string(dir.path().join(&out)).unwrap();
            let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
            assert!(!rows.is_empty(), "{out}");
            for row in &rows {
                assert_eq!(row.len(), 5, "{out}: {row:?}");
                if !row[4].is_empty() {
                    let (sheet, next) = (row[0], row[4]);
                    assert!(
                        rows.iter().any(|r| r[0] == sheet && r[1] == next),
                        "{out}: next {next} of sheet {sheet} is no point"
                    );
                }
            }
        }
    }
}

#[test]
fn the_profile_export_writes_the_paper_modes_profile_beside_the_physical_one() {
    // Both modes' emission by altitude, exported; each line's paper peak
    // within 20 km of the physical one (the library test holds the same for defaults).
    let dir = tempfile::tempdir().unwrap();
    ok(
        dir.path(),
        &[
            "export",
            "aurora-profile",
            "--energy-kev",
            "2",
            "--flux-erg",
            "5",
            "--out",
            "phys.csv",
            "--paper",
            "paper.csv",
        ],
    );
    let read = |name: &str| -> Vec<Vec<f64>> {
        let text = std::fs::read_to_string(dir.path().join(name)).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next().unwrap().split(',').count(), 6, "{name}: six columns");
        lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect()
    };
    let (phys, paper) = (read("phys.csv"), read("paper.csv"));
    let peak = |rows: &[Vec<f64>], col: usize| {
        rows.iter().max_by(|a, b| a[col].total_cmp(&b[col])).map(|r| r[0]).unwrap()
    };
    for col in 1..=5 {
        let (a, b) = (peak(&phys, col), peak(&paper, col));
        assert!((a - b).abs() <= 20.0, "column {col}: physical peak {a} km, paper {b} km");
    }
}
