//! `render` writes every frame, in PNG or EXR, with optional per-frame stats.

use crate::{TINY_FLAME, ok, png_size, write};

#[test]
fn renders_numbered_png_frames_and_stats() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    let out = dir.path().join("out/nested");
    let stdout =
        ok(dir.path(), &["render", &scene, "--out", out.to_str().unwrap(), "--stats", "stats.jsonl"]);
    assert!(stdout.contains("wrote 4 frame(s)"), "{stdout}");
    let mut names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["frame_00000.png", "frame_00001.png", "frame_00002.png", "frame_00003.png"]);
    assert_eq!(png_size(&out.join("frame_00003.png")), (64, 36));
    let stats = std::fs::read_to_string(dir.path().join("stats.jsonl")).unwrap();
    let lines: Vec<&str> = stats.lines().collect();
    assert_eq!(lines.len(), 4);
    for (k, line) in lines.iter().enumerate() {
        assert!(line.starts_with(&format!("{{\"frame\":{k},\"particles\":")), "{line}");
        for field in ["\"step_ms\":", "\"render_ms\":", "\"emitted\":20", "\"skipped\":false"] {
            assert!(line.contains(field), "{field} missing from {line}");
        }
    }
}

#[test]
fn frame_ranges_and_size_overrides() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    ok(dir.path(), &["render", &scene, "--out", "o", "--frames", "5..=6", "--width", "40", "--height", "20"]);
    let mut names: Vec<String> = std::fs::read_dir(dir.path().join("o"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["frame_00005.png", "frame_00006.png"]);
    assert_eq!(png_size(&dir.path().join("o/frame_00006.png")), (40, 20));
}

#[test]
fn exr_frames_hold_linear_radiance() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    ok(dir.path(), &["render", &scene, "--out", "o", "--frames", "3", "--format", "exr"]);
    let bytes = std::fs::read(dir.path().join("o/frame_00003.exr")).unwrap();
    // OpenEXR magic number 20000630, little endian.
    assert_eq!(&bytes[..4], &[0x76, 0x2f, 0x31, 0x01]);
    // The flame is brighter than any 8-bit white would allow after exposure: values are
    // scene-referred floats, so the file is far larger than its PNG.
    assert!(bytes.len() > 64 * 36 * 3 * 4 / 2);
}

#[test]
fn density_view_draws_particles() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    ok(dir.path(), &["render", &scene, "--out", "o", "--frames", "3", "--view", "density"]);
    assert_eq!(png_size(&dir.path().join("o/frame_00003.png")), (64, 36));
}
