//! `new` writes a valid starter scene; `demo` renders the showcase.

use crate::{fails, ok, png_size};

#[test]
fn new_writes_a_valid_commented_scene_and_refuses_to_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    ok(dir.path(), &["new", "flame", "scenes/my-flame.toml"]);
    let text = std::fs::read_to_string(dir.path().join("scenes/my-flame.toml")).unwrap();
    assert!(text.contains("# A phenomena flame scene"));
    ok(dir.path(), &["validate", "scenes/my-flame.toml"]);
    let e = fails(dir.path(), &["new", "flame", "scenes/my-flame.toml"]);
    assert!(e.contains("already exists"), "{e}");
    ok(dir.path(), &["new", "flame", "scenes/my-flame.toml", "--force"]);
}

/// `new` knows every registered phenomenon, and each starter validates and renders.
#[test]
fn every_phenomenon_has_a_starter_that_validates_and_renders() {
    let dir = tempfile::tempdir().unwrap();
    for p in phenomena_scene::registry::PHENOMENA {
        let name = p.name();
        let out = ok(dir.path(), &["new", name]);
        let file = format!("{name}.toml");
        assert!(out.contains(&format!("wrote {file}")), "{out}");
        ok(dir.path(), &["validate", &file]);
        ok(dir.path(), &["render", &file, "--out", name, "--frames", "0", "--width", "64", "--height", "36"]);
        assert_eq!(png_size(&dir.path().join(name).join("frame_00000.png")), (64, 36), "{name}");
    }
    // A phenomenon that does not exist is a malformed command line (exit 2) listing
    // the registered ones.
    let out = crate::run(dir.path(), &["new", "lava"]);
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("[possible values: flame, aurora, snow, sparkle, shot]"), "{e}");
}

#[test]
#[ignore = "slow tier: cargo test -- --include-ignored"]
fn demo_renders_every_system() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = ok(dir.path(), &["demo", "--out", "d"]);
    assert!(stdout.contains("demo written to d"), "{stdout}");
    let d = dir.path().join("d");
    assert_eq!(png_size(&d.join("flame-campfire/frame_00149.png")), (960, 540));
    assert_eq!(std::fs::read_dir(d.join("flame-campfire")).unwrap().count(), 120);
    for still in ["flame-paper", "flame-wind-left", "flame-wind-right"] {
        assert_eq!(png_size(&d.join(still).join("frame_00120.png")), (640, 360));
    }
    assert_eq!(png_size(&d.join("aurora-scene2/frame_00230.png")), (640, 360));
    assert_eq!(png_size(&d.join("snow-table/frame_00059.png")), (640, 480));
    assert_eq!(png_size(&d.join("winter-night/frame_00200.png")), (960, 540));
    assert_eq!(png_size(&d.join("blackbody-1000K-10000K.png")), (901, 1));
}
