//! Sparkle scenes through the CLI: frames and `--stats` for both methods, the empty-cone
//! warning, identical frames for any thread count, and bad input located in the file.

use crate::{fails, ok, run, write};

/// 2·10⁵ crystals (10 per m³ in the 20,000 m³ box below), n = 200.
const TINY_DUST: &str = r#"
[scene]
frames = 3
width = 96
height = 54
seed = 4

[sparkle]
method = "stochastic"

[sparkle.phong]
threshold_i_e = 0.05
exponent_n = 200.0

[sparkle.population]
kind = "diamond-dust"
box_min_m = [-50.0, 0.0, -40.0]
box_max_m = [50.0, 5.0, 0.0]
density_per_m3 = 10.0
"#;

#[test]
fn dust_renders_with_stats_for_both_methods() {
    let dir = tempfile::tempdir().unwrap();
    for method in ["stochastic", "brute-force"] {
        let scene = write(dir.path(), &format!("{method}.toml"), &TINY_DUST.replace("stochastic", method));
        ok(dir.path(), &["render", &scene, "--out", method, "--stats", &format!("{method}.jsonl")]);
        assert_eq!(std::fs::read_dir(dir.path().join(method)).unwrap().count(), 3);
        let stats = std::fs::read_to_string(dir.path().join(format!("{method}.jsonl"))).unwrap();
        let last: serde_json::Value = serde_json::from_str(stats.lines().last().unwrap()).unwrap();
        assert_eq!(last["virtual_count"], 200_000, "{last}");
        // p = (1 - 0.05^(1/200))/2 = 7.4e-3: about 1,480 seen of 2·10⁵.
        let seen = last["generated"].as_u64().unwrap();
        assert!((1200..1800).contains(&seen), "{method}: {seen}");
        let bytes = last["bytes_held"].as_u64().unwrap();
        if method == "brute-force" {
            assert!(bytes >= 200_000 * 28, "{bytes}");
        } else {
            assert!(bytes < 200_000, "{bytes}");
        }
    }
}

#[test]
fn sparkle_frames_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "d.toml", TINY_DUST);
    ok(dir.path(), &["render", &scene, "--out", "a", "--threads", "1", "--format", "exr", "--frames", "2"]);
    ok(dir.path(), &["render", &scene, "--out", "b", "--threads", "2", "--format", "exr", "--frames", "2"]);
    let read = |d: &str| std::fs::read(dir.path().join(d).join("frame_00002.exr")).unwrap();
    assert_eq!(read("a"), read("b"));
}

#[test]
fn an_empty_cone_warns_and_renders_the_background() {
    let dir = tempfile::tempdir().unwrap();
    let scene =
        write(dir.path(), "e.toml", &TINY_DUST.replace("threshold_i_e = 0.05", "threshold_i_e = 1.5"));
    let out = run(dir.path(), &["render", &scene, "--out", "e"]);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no facet can be seen") && err.contains("threshold_i_e 1.5"), "{err}");
}

#[test]
fn bad_sparkle_values_are_located() {
    let dir = tempfile::tempdir().unwrap();
    let text = TINY_DUST
        .replace("exponent_n = 200.0", "exponent_n = -3.0")
        .replace("density_per_m3 = 10.0", "density_per_m3 = 0.0");
    let scene = write(dir.path(), "bad.toml", &text);
    let err = fails(dir.path(), &["render", &scene, "--out", "o"]);
    assert!(err.contains("bad.toml:13:14: sparkle.phong.exponent_n = -3"), "{err}");
    assert!(err.contains("bad.toml:19:18: sparkle.population.density_per_m3 = 0"), "{err}");
    let scene = write(
        dir.path(),
        "huge.toml",
        &TINY_DUST
            .replace("stochastic", "brute-force")
            .replace("density_per_m3 = 10.0", "density_per_m3 = 100000.0"),
    );
    let err = fails(dir.path(), &["render", &scene, "--out", "o"]);
    assert!(err.contains("use the stochastic method"), "{err}");
}

#[test]
fn glints_go_over_a_background_image_stretched_to_the_frame() {
    let dir = tempfile::tempdir().unwrap();
    let red = image::RgbImage::from_pixel(96, 54, image::Rgb([200, 30, 30]));
    red.save(dir.path().join("bg.png")).unwrap();
    let text = format!("{TINY_DUST}\n[render]\nbackground = {{ kind = \"image\", path = \"bg.png\" }}\n");
    let scene = write(dir.path(), "bg.toml", &text);
    ok(dir.path(), &["render", &scene, "--out", "o", "--frames", "0"]);
    let png = image::open(dir.path().join("o/frame_00000.png")).unwrap().to_rgb8();
    let reddish = png.pixels().filter(|p| u32::from(p.0[0]) > 2 * u32::from(p.0[2]) + 40).count();
    assert!(reddish > 96 * 54 / 2, "{reddish}");
    // Another frame size: the image is stretched to it (the rule of every phenomenon).
    ok(dir.path(), &["render", &scene, "--out", "o2", "--width", "64", "--frames", "0"]);
    let png = image::open(dir.path().join("o2/frame_00000.png")).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (64, 54));
    let reddish = png.pixels().filter(|p| u32::from(p.0[0]) > 2 * u32::from(p.0[2]) + 40).count();
    assert!(reddish > 64 * 54 / 2, "{reddish}");
}
