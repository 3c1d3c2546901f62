//! Bad input gets a clear error with file:line:column, never a panic or a stray file.

use crate::{TINY_FLAME, fails, ok, run, write};

#[test]
fn syntax_errors_name_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "bad.toml", "[scene]\nframes = 3\n[flame]\nmode = paper\n");
    let e = fails(dir.path(), &["validate", &scene]);
    assert!(e.contains("bad.toml:4:8:"), "{e}");
    let e = fails(dir.path(), &["render", &scene, "--out", "o"]);
    assert!(e.contains("bad.toml:4:8:"), "{e}");
    assert!(!dir.path().join("o").exists(), "nothing is written for a bad scene");
}

#[test]
fn vectors_need_exactly_three_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "v.toml", "[flame.emitter]\nposition_m = [0, 0, 0, 5]\n");
    let e = fails(dir.path(), &["validate", &scene]);
    assert!(e.contains("v.toml:2:14: expected an array of exactly 3 numbers, found 4"), "{e}");
}

#[test]
fn unknown_keys_and_out_of_range_values_are_all_reported() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "typo.toml", "[flame]\n[flame.emitter]\nrate = 5\n");
    let e = fails(dir.path(), &["validate", &scene]);
    assert!(e.contains("typo.toml:3:1: unknown field `rate`"), "{e}");
    let scene = write(
        dir.path(),
        "range.toml",
        "[scene]\nframes = 0\n[flame.sph]\nsupport_radius_m = -0.1\n[render]\nresolution_scale = 3.0\n",
    );
    let e = fails(dir.path(), &["validate", &scene]);
    assert!(e.contains("range.toml:2:10: scene.frames = 0: expected an integer in [1, 1000000]"), "{e}");
    assert!(
        e.contains("range.toml:4:20: flame.sph.support_radius_m = -0.1: expected a value in [0.0001, 100]"),
        "{e}"
    );
    assert!(
        e.contains("range.toml:6:20: render.resolution_scale = 3: expected a value in [0.125, 1]"),
        "{e}"
    );
}

#[test]
fn missing_files_and_unwritable_outputs_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let e = fails(dir.path(), &["render", "nope.toml", "--out", "o"]);
    assert!(e.contains("nope.toml: cannot read the scene file"), "{e}");
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    write(dir.path(), "file", "not a directory");
    let e = fails(dir.path(), &["render", &scene, "--out", "file"]);
    assert!(e.contains("file exists and is not a directory"), "{e}");
    let e = fails(dir.path(), &["render", &scene, "--out", "file/sub"]);
    assert!(e.contains("cannot create the output directory"), "{e}");
    let img = write(
        dir.path(),
        "img.toml",
        "[flame]\n[render.background]\nkind = \"image\"\npath = \"missing.png\"\n",
    );
    let e = fails(dir.path(), &["render", &img, "--out", "o2", "--frames", "0"]);
    assert!(e.contains("img.toml:4:8: render.background.path = \"missing.png\": no such file"), "{e}");
}

#[test]
fn command_line_values_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    // clap rejects these itself (exit 2) with the valid range.
    let out = run(dir.path(), &["render", &scene, "--out", "o", "--width", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("1..=16384"));
    let out = run(dir.path(), &["render", &scene, "--out", "o", "--frames", "9..3"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("empty range"));
    let e = fails(dir.path(), &["render", &scene, "--out", "o", "--frames", "3..6"]);
    assert!(e.contains("--frames 3..6 goes past the scene's 4 frames"), "{e}");
    let e = fails(dir.path(), &["render", &scene, "--out", "o", "--frames", "4000000000"]);
    assert!(e.contains("goes past the scene's 4 frames"), "{e}");
    ok(dir.path(), &["validate", &scene]);
}

#[cfg(not(feature = "studio"))]
#[test]
fn studio_without_the_feature_says_how_to_build_it() {
    let dir = tempfile::tempdir().unwrap();
    let e = fails(dir.path(), &["studio", "--port", "0"]);
    assert!(e.contains("--features studio"), "{e}");
}
