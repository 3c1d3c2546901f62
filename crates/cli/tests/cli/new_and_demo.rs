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

#[test]
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
    assert_eq!(png_size(&d.join("blackbody-1000K-10000K.png")), (901, 1));
}
