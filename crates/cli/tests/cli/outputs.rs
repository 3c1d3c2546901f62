//! The outputs shots are finished with. VDB volumes and PLY caches per frame,
//! flipbooks of all frames; formats a phenomenon cannot write are refused before
//! anything is simulated. (The real clients, OpenVDB and Blender, read these in
//! `.ci/run`: `tools/vdb-check/check_frames.py`, `tools/blender-check/check.py`.)

use std::path::Path;

use crate::{TINY_FLAME, fails, ok, write};

fn shipped(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name).to_string_lossy().into_owned()
}

/// The cells of a flipbook atlas as RGBA bytes, in frame order.
fn cells(dir: &Path) -> (serde_json::Value, Vec<Vec<u8>>) {
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("flipbook.json")).unwrap()).unwrap();
    let atlas = image::open(dir.join("flipbook.png")).unwrap().to_rgba8();
    let n = |k: &str| json[k].as_u64().unwrap() as u32;
    assert_eq!((atlas.width(), atlas.height()), (n("atlas_width"), n("atlas_height")));
    let (fw, fh, cols) = (n("frame_width"), n("frame_height"), n("columns"));
    let frames = (0..n("frames"))
        .map(|j| {
            let (cx, cy) = (j % cols * fw, j / cols * fh);
            let mut cell = Vec::new();
            for y in cy..cy + fh {
                for x in cx..cx + fw {
                    cell.extend_from_slice(&atlas.get_pixel(x, y).0);
                }
            }
            cell
        })
        .collect();
    (json, frames)
}

/// Mean absolute difference of two cells' premultiplied colour (what is seen over
/// black), 8-bit units.
fn difference(a: &[u8], b: &[u8]) -> f64 {
    let seen = |p: &[u8]| -> [f64; 3] { [0, 1, 2].map(|k| f64::from(p[k]) * f64::from(p[3]) / 255.0) };
    let total: f64 = a
        .chunks(4)
        .zip(b.chunks(4))
        .map(|(p, q)| {
            let (p, q) = (seen(p), seen(q));
            (0..3).map(|k| (p[k] - q[k]).abs()).sum::<f64>()
        })
        .sum();
    total / (a.len() / 4 * 3) as f64
}

#[test]
fn a_looped_flipbook_has_no_seam() {
    let dir = tempfile::tempdir().unwrap();
    let scene = shipped("flame-paper.toml");
    // A steady stretch of the flame (it has grown for a second by frame 60).
    let args =
        ["render", &scene, "--frames", "60..100", "--width", "48", "--height", "64", "--format", "flipbook"];
    let out = ok(dir.path(), &[&args[..], &["--out", "loop", "--loop", "8"]].concat());
    assert!(out.contains("flipbook of 32 frame(s)"), "{out}");
    let (json, looped) = cells(&dir.path().join("loop"));
    assert_eq!(json["loop_frames"], 8);
    assert_eq!(json["fps"], 60.0);
    assert_eq!(json["source_frames"], serde_json::json!([60, 100]));
    let steps: Vec<f64> = looped.windows(2).map(|w| difference(&w[0], &w[1])).collect();
    let seam = difference(&looped[looped.len() - 1], &looped[0]);
    let largest = steps.iter().copied().fold(0.0, f64::max);
    assert!(seam <= largest, "the seam differs by {seam:.2}, consecutive frames by at most {largest:.2}");
    // Without the loop the seam is a jump: the test can tell.
    ok(dir.path(), &[&args[..], &["--out", "plain"]].concat());
    let (_, plain) = cells(&dir.path().join("plain"));
    assert_eq!(plain.len(), 40);
    // Past the cross-fade the looped frames are the plain ones.
    assert_eq!(looped[8..], plain[8..32]);
    let plain_steps = plain.windows(2).map(|w| difference(&w[0], &w[1])).fold(0.0, f64::max);
    let plain_seam = difference(&plain[39], &plain[0]);
    assert!(plain_seam > plain_steps, "the unlooped seam {plain_seam:.2} vs steps {plain_steps:.2}");
}

#[test]
fn flipbook_alpha_modes_and_power_of_two_cells() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", &TINY_FLAME.replace("frames = 4", "frames = 12"));
    let base = ["render", &scene, "--format", "flipbook", "--width", "60", "--height", "30"];
    ok(dir.path(), &[&base[..], &["--out", "s"]].concat());
    ok(dir.path(), &[&base[..], &["--out", "p", "--alpha", "premultiplied"]].concat());
    let (js, s) = cells(&dir.path().join("s"));
    let (jp, p) = cells(&dir.path().join("p"));
    assert_eq!((js["alpha"].as_str(), jp["alpha"].as_str()), (Some("straight"), Some("premultiplied")));
    // Straight colour × alpha over black is the premultiplied colour (8-bit rounding,
    // and sRGB encoding of each: within 2 codes of the brighter).
    for (a, b) in s.iter().zip(&p) {
        for (x, y) in a.chunks(4).zip(b.chunks(4)) {
            assert_eq!(x[3], y[3]);
        }
    }
    assert!(difference(&s[11], &p[11]) < 2.0);
    // A flipbook is drawn over black: the tiny flame's corners are transparent.
    assert_eq!(s[11][3], 0);
    ok(dir.path(), &[&base[..], &["--out", "pot", "--pot"]].concat());
    let (j, _) = cells(&dir.path().join("pot"));
    for k in ["atlas_width", "atlas_height", "frame_width", "frame_height"] {
        assert!(j[k].as_u64().unwrap().is_power_of_two(), "{k} = {}", j[k]);
    }
    assert_eq!((j["frame_width"].as_u64(), j["frame_height"].as_u64()), (Some(64), Some(32)));
}

/// `--crop` cuts every cell to what the frames show: the cropped cells are the
/// uncropped cells' `crop` rectangle, pixel for pixel, and nothing lit is cut off.
#[test]
fn a_cropped_flipbook_keeps_every_lit_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let scene = shipped("flame-paper.toml");
    let args =
        ["render", &scene, "--frames", "60..64", "--width", "160", "--height", "90", "--format", "flipbook"];
    ok(dir.path(), &[&args[..], &["--out", "full"]].concat());
    ok(dir.path(), &[&args[..], &["--out", "crop", "--crop"]].concat());
    let (jf, full) = cells(&dir.path().join("full"));
    let (jc, crop) = cells(&dir.path().join("crop"));
    assert!(jf.get("crop").is_none(), "{jf}");
    let rect: Vec<u32> = jc["crop"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as u32).collect();
    let [x0, y0, w, h] = [rect[0], rect[1], rect[2], rect[3]];
    assert_eq!(
        (jc["frame_width"].as_u64(), jc["frame_height"].as_u64()),
        (Some(u64::from(w)), Some(u64::from(h)))
    );
    // The flame is a narrow column: most of the 160x90 frame goes.
    assert!(w * h * 3 < 160 * 90, "cropped to {w}x{h}");
    for (f, c) in full.iter().zip(&crop) {
        let mut inside = Vec::new();
        for (i, px) in f.chunks(4).enumerate() {
            let (x, y) = (i as u32 % 160, i as u32 / 160);
            if (x0..x0 + w).contains(&x) && (y0..y0 + h).contains(&y) {
                inside.extend_from_slice(px);
            } else {
                assert_eq!(px[3], 0, "a lit pixel at ({x}, {y}) outside the crop {rect:?}");
            }
        }
        assert_eq!(&inside, c);
    }
}

#[test]
fn volumes_and_caches_per_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    ok(dir.path(), &["render", &scene, "--out", "v", "--format", "vdb", "--frames", "2..4"]);
    for f in [2, 3] {
        let vdb = std::fs::read(dir.path().join(format!("v/frame_{f:05}.vdb"))).unwrap();
        assert_eq!(&vdb[..8], &0x5644_4220_i64.to_le_bytes(), "OpenVDB's magic number");
        let manifest: serde_json::Value = serde_json::from_slice(
            &std::fs::read(dir.path().join(format!("v/frame_{f:05}.vdb.json"))).unwrap(),
        )
        .unwrap();
        let names: Vec<&str> =
            manifest["grids"].as_array().unwrap().iter().map(|g| g["name"].as_str().unwrap()).collect();
        assert_eq!(names, ["density", "temperature", "emission"]);
        assert_eq!(manifest["grids"][0]["voxel_size_m"], 0.01);
        assert!(manifest["grids"][0]["active_voxels"].as_u64().unwrap() > 0);
    }
    ok(dir.path(), &["render", &scene, "--out", "c", "--format", "ply", "--frames", "3"]);
    let ply = std::fs::read(dir.path().join("c/frame_00003.ply")).unwrap();
    let text = String::from_utf8_lossy(&ply[..400]);
    assert!(text.starts_with("ply\nformat binary_little_endian 1.0\n"), "{text}");
    for p in [
        "property float x",
        "property float vz",
        "property float temperature",
        "property float density",
        "property uint id",
    ] {
        assert!(text.contains(p), "{p} missing:\n{text}");
    }
    let n: usize = text.lines().find_map(|l| l.strip_prefix("element vertex ")).unwrap().parse().unwrap();
    let header = text.find("end_header\n").unwrap() + "end_header\n".len();
    assert_eq!(ply.len(), header + n * 9 * 4, "9 four-byte properties per particle");
    // A coarser grid: fewer voxels, and a voxel size out of range is refused.
    ok(
        dir.path(),
        &["render", &scene, "--out", "v2", "--format", "vdb", "--frames", "3", "--voxel-m", "0.04"],
    );
    let e = fails(
        dir.path(),
        &["render", &scene, "--out", "v3", "--format", "vdb", "--frames", "3", "--voxel-m", "0"],
    );
    assert!(e.contains("voxel size 0 m"), "{e}");
}

/// `--motion` writes a motion atlas beside the colour, cell for cell (cropped and
/// looped alike); decoded, the flame's light moves up the frame (its gas rises), more
/// near its tip than its base (buoyancy accelerates it), and not sideways on average.
#[test]
fn a_motion_flipbook_says_where_the_flame_moves() {
    let dir = tempfile::tempdir().unwrap();
    let scene = shipped("flame-paper.toml");
    let args =
        ["render", &scene, "--frames", "60..72", "--width", "96", "--height", "128", "--format", "flipbook"];
    ok(dir.path(), &[&args[..], &["--out", "m", "--motion", "--crop", "--loop", "2"]].concat());
    let out = dir.path().join("m");
    let (json, colour) = cells(&out);
    let scale = json["motion"]["scale_px"].as_f64().unwrap();
    assert_eq!(json["motion"]["image"], "flipbook_motion.png");
    let motion = image::open(out.join("flipbook_motion.png")).unwrap().to_rgba8();
    let n = |k: &str| json[k].as_u64().unwrap() as u32;
    assert_eq!((motion.width(), motion.height()), (n("atlas_width"), n("atlas_height")));
    let (fw, fh, cols) = (n("frame_width"), n("frame_height"), n("columns"));
    let decode = |v: u8| (f64::from(v) - 128.0) / 127.0 * scale;
    // Lit pixels' vectors, split at the middle of the lit rows.
    let (mut low, mut high, mut sideways) = (Vec::new(), Vec::new(), Vec::new());
    for (j, cell) in colour.iter().enumerate() {
        let lit: Vec<(u32, u32)> =
            (0..fw * fh).filter(|i| cell[*i as usize * 4 + 3] > 64).map(|i| (i % fw, i / fw)).collect();
        let (top, bottom) = lit.iter().fold((u32::MAX, 0), |(t, b), p| (t.min(p.1), b.max(p.1)));
        for &(x, y) in &lit {
            let px = motion.get_pixel(j as u32 % cols * fw + x, j as u32 / cols * fh + y).0;
            let (dx, dy) = (decode(px[0]), decode(px[1]));
            sideways.push(dx);
            if y < (top + bottom) / 2 { high.push(dy) } else { low.push(dy) }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (up_low, up_high) = (-mean(&low), -mean(&high));
    assert!(up_low > 0.0 && up_high > up_low, "rising {up_low:.2} px low, {up_high:.2} px high");
    // The flame is symmetric about its axis.
    assert!(mean(&sideways).abs() < 0.25 * up_high, "sideways {:.2} px", mean(&sideways));
}

#[test]
fn formats_a_phenomenon_cannot_write_are_refused_first() {
    let dir = tempfile::tempdir().unwrap();
    let snow = shipped("snow-table.toml");
    let e = fails(dir.path(), &["render", &snow, "--out", "o", "--format", "vdb"]);
    assert!(e.contains("snow scenes are not written as vdb: use png, exr"), "{e}");
    let aurora = shipped("aurora-scene1.toml");
    let e = fails(dir.path(), &["render", &aurora, "--out", "o", "--format", "flipbook"]);
    assert!(e.contains("aurora scenes are not written as flipbook"), "{e}");
    // A loop longer than half the frames, and a flipbook too large, before simulating.
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    let e = fails(dir.path(), &["render", &scene, "--out", "o", "--format", "flipbook", "--loop", "3"]);
    assert!(e.contains("--loop 3 needs at least 6 frames"), "{e}");
    let e = fails(dir.path(), &["render", &scene, "--out", "o", "--format", "flipbook", "--width", "9000"]);
    assert!(e.contains("over 16384 a side"), "{e}");
    let e = fails(dir.path(), &["render", &scene, "--out", "o", "--format", "flipbook", "--resume"]);
    assert!(e.contains("--resume"), "{e}");
    let sparkle = shipped("sparkle-paper.toml");
    let e = fails(dir.path(), &["render", &sparkle, "--out", "o", "--format", "flipbook", "--motion"]);
    assert!(e.contains("--motion: sparkle scenes have no motion vectors"), "{e}");
    assert!(!dir.path().join("o").join("flipbook.png").exists());
}

/// Run `render` with each case's arguments, all refused before the run (not when a
/// frame is written, "frame N: ...") with the case's words, no file written.
fn refused_before_the_first_frame(cases: &[(&str, Vec<&str>, &str)]) {
    let dir = tempfile::tempdir().unwrap();
    for (out, args, needle) in cases {
        let mut all = vec!["render", "--out", out];
        all.extend(args.iter().copied());
        let e = fails(dir.path(), &all);
        assert!(e.contains(needle), "{out}: {e}");
        assert!(!e.contains("frame 30") && !e.contains("frame 40") && !e.contains("frame 0"), "{out}: {e}");
        let written = std::fs::read_dir(dir.path().join(out)).map_or(0, |d| d.count());
        assert_eq!(written, 0, "{out}: files written");
    }
}

/// Volumes count against the memory budget and their voxel size is checked before the
/// first frame: tiny voxels (the flame's 0.1 mm needed an 8 GB list and aborted; the
/// aurora's 0.1 km, inside the documented range, tens of GB), an invalid size, and a
/// volume over the budget are refused at once, naming the size.
#[test]
fn volumes_over_the_memory_budget_are_refused_before_the_first_frame() {
    let flame = shipped("flame-paper.toml");
    let aurora = shipped("aurora-scene2.toml");
    let small = ["--width", "64", "--height", "36"];
    refused_before_the_first_frame(&[
        (
            "tiny",
            vec![&flame, "--format", "vdb", "--voxel-m", "0.0001", "--frames", "40..41"],
            "use larger voxels",
        ),
        ("zero", vec![&flame, "--format", "vdb", "--voxel-m", "0", "--frames", "40..41"], "voxel size 0 m"),
        (
            "nan",
            vec![&flame, "--format", "vdb", "--voxel-m", "NaN", "--frames", "40..41"],
            "voxel size NaN m",
        ),
        (
            "aurora",
            [&[aurora.as_str(), "--format", "vdb", "--voxel-km", "0.1", "--frames", "30..31"][..], &small]
                .concat(),
            "use larger voxels",
        ),
        (
            "budget",
            [
                &[flame.as_str(), "--format", "vdb", "--voxel-m", "0.002", "--frames", "40..41"][..],
                &small,
                &["--max-memory-gib", "0.05"],
            ]
            .concat(),
            "the budget",
        ),
    ]);
}

/// A flipbook's atlas counts against the budget: nine 4096² frames need more than 1 GiB
/// beside the flame, refused before the first frame.
#[test]
fn a_flipbook_over_the_memory_budget_is_refused_before_the_first_frame() {
    let flame = shipped("flame-paper.toml");
    refused_before_the_first_frame(&[(
        "atlas",
        vec![
            &flame,
            "--format",
            "flipbook",
            "--frames",
            "9",
            "--width",
            "4096",
            "--height",
            "4096",
            "--max-memory-gib",
            "1",
        ],
        "more than the budget of 1.00 GiB",
    )]);
}
