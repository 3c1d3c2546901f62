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
        assert!(line.starts_with(&format!("{{\"frame\":{k},\"step_ms\":")), "{line}");
        for field in
            ["\"render_ms\":", "\"particles\":", "\"emitted\":20", "\"neighbor_pairs\":", "\"skipped\":false"]
        {
            assert!(line.contains(field), "{field} missing from {line}");
        }
    }
}

#[test]
fn frame_ranges_and_size_overrides() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    ok(dir.path(), &["render", &scene, "--out", "o", "--frames", "2..=3", "--width", "40", "--height", "20"]);
    let mut names: Vec<String> = std::fs::read_dir(dir.path().join("o"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["frame_00002.png", "frame_00003.png"]);
    assert_eq!(png_size(&dir.path().join("o/frame_00003.png")), (40, 20));
}

#[test]
fn exr_frames_hold_the_linear_radiance_that_the_png_tone_maps() {
    use exr::prelude::*;
    use phenomena_core::color::srgb_encode_u8;
    use phenomena_core::tonemap::{Exposure, ToneMap};
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    ok(dir.path(), &["render", &scene, "--out", "o", "--frames", "3", "--format", "exr"]);
    ok(dir.path(), &["render", &scene, "--out", "o", "--frames", "3"]);
    let image = read_first_rgba_layer_from_file(
        dir.path().join("o/frame_00003.exr"),
        |resolution, _| vec![vec![[0.0f32; 3]; resolution.width()]; resolution.height()],
        |px, pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y()][pos.x()] = [r, g, b],
    )
    .unwrap();
    let pixels = &image.layer_data.channel_data.pixels;
    assert_eq!((pixels.len(), pixels[0].len()), (36, 64));
    // Linear, scene-referred: the flame's core is brighter than display white.
    let max = pixels.iter().flatten().flatten().fold(0.0f32, |m, &v| m.max(v));
    assert!(max > 1.0, "max radiance {max}");
    // Tone mapping the EXR's values as the PNG writer does gives the PNG's bytes.
    let png = image::open(dir.path().join("o/frame_00003.png")).unwrap().to_rgb8();
    let exposure = Exposure { ev: 0.0, tone_map: ToneMap::Aces };
    for (y, row) in pixels.iter().enumerate() {
        for (x, px) in row.iter().enumerate() {
            let expect = px.map(|v| srgb_encode_u8(exposure.apply(v)));
            assert_eq!(png.get_pixel(x as u32, y as u32).0, expect, "pixel ({x}, {y})");
        }
    }
}

#[test]
fn density_view_draws_particles() {
    let dir = tempfile::tempdir().unwrap();
    // The camera close to the burner (the default frames the paper flame's whole height
    // since issue 38, and its first frames would cover only a dozen pixels of 64x36).
    let close = "\n[render.camera]\nposition = [0.0, 0.45, 2.2]\nlook_at = [0.0, 0.45, 0.0]\nprojection = { kind = \"perspective\", fov_y_deg = 35.0 }\n";
    let scene = write(dir.path(), "tiny.toml", &format!("{TINY_FLAME}{close}"));
    ok(dir.path(), &["render", &scene, "--out", "o", "--frames", "3", "--view", "density"]);
    let img = image::open(dir.path().join("o/frame_00003.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (64, 36));
    // Fig 7: coloured squares over black; the burner region is covered.
    let coloured = img.pixels().filter(|p| p.0 != [0, 0, 0]).count();
    assert!(coloured > 20 && coloured < 64 * 36, "{coloured} coloured pixels");
}
