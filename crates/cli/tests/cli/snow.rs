//! Snow scenes through the CLI: frames of the scene and of the probability, the snow
//! mesh export in three formats, and bad input.

use crate::{fails, ok, write};

const TINY_SNOW: &str = "[scene]\nframes = 4\nwidth = 80\nheight = 60\n[geometry]\nbuiltin = \"table\"\n[snow]\nmap_resolution = 32\ndirections = 8\nshadow_resolution = 64\nrate_cm_per_h = 20.0\n";

#[test]
fn a_snow_scene_renders_its_frames_and_probability() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "snow.toml", TINY_SNOW);
    ok(dir.path(), &["render", &scene, "--out", "f"]);
    assert_eq!(std::fs::read_dir(dir.path().join("f")).unwrap().count(), 4);
    ok(dir.path(), &["render", &scene, "--out", "p", "--view", "probability", "--frames", "0"]);
    let png = image::open(dir.path().join("p/frame_00000.png")).unwrap().to_rgb8();
    // Panels of exposed (light) and shaded (dark) texels.
    let light = png.pixels().filter(|p| p.0[0] > 180).count();
    let dark = png.pixels().filter(|p| p.0[2] > 10 && p.0[0] < 60).count();
    assert!(light > 100 && dark > 10, "light {light}, dark {dark}");
    let err = fails(dir.path(), &["render", &scene, "--out", "x", "--view", "sky"]);
    assert!(err.contains("not a snow view"), "{err}");
}

#[test]
fn the_snow_mesh_exports_as_glb_obj_and_ply() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "snow.toml", TINY_SNOW);
    let out = ok(
        dir.path(),
        &["export", "snow-mesh", &scene, "--format", "glb", "--time-h", "0.3", "--out", "m/snow.glb"],
    );
    assert!(out.contains("3 steps"), "{out}");
    let glb = std::fs::read(dir.path().join("m/snow.glb")).unwrap();
    assert_eq!(&glb[..4], b"glTF");
    ok(dir.path(), &["export", "snow-mesh", &scene, "--format", "obj", "--out", "m/snow.obj"]);
    let obj = std::fs::read_to_string(dir.path().join("m/snow.obj")).unwrap();
    assert!(obj.lines().any(|l| l.starts_with("f ")));
    ok(dir.path(), &["export", "snow-mesh", &scene, "--format", "ply", "--out", "m/snow.ply"]);
    assert!(
        std::fs::read(dir.path().join("m/snow.ply"))
            .unwrap()
            .starts_with(b"ply\nformat binary_little_endian")
    );
    // Not a snow scene; a bad time.
    let flame = write(dir.path(), "f.toml", crate::TINY_FLAME);
    let err = fails(dir.path(), &["export", "snow-mesh", &flame, "--out", "x.glb"]);
    assert!(err.contains("flame scene"), "{err}");
    let err = fails(dir.path(), &["export", "snow-mesh", &scene, "--time-h=-1", "--out", "x.glb"]);
    assert!(err.contains("--time-h -1"), "{err}");
}

#[test]
fn bad_snow_settings_are_located() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "bad.toml",
        "[scene]\nframes = 2\n[geometry]\nbuiltin = \"house\"\n[snow]\nrepose_deg = 95.0\ndirections = 0\n",
    );
    let err = fails(dir.path(), &["render", &scene, "--out", "o"]);
    assert!(err.contains("bad.toml:4:11") && err.contains("house"), "{err}");
    let scene =
        write(dir.path(), "bad2.toml", "[scene]\nframes = 2\n[snow]\nrepose_deg = 95.0\ndirections = 0\n");
    let err = fails(dir.path(), &["render", &scene, "--out", "o"]);
    assert!(err.contains("bad2.toml:4:14: snow.repose_deg = 95"), "{err}");
    assert!(err.contains("bad2.toml:5:14: snow.directions = 0"), "{err}");
}

/// A 4 m floor and a 1 m platform 0.5 m up, as OBJ (y up), plus one degenerate face.
const PLATFORM_OBJ: &str = "o floor\nv -2 0 -2\nv -2 0 2\nv 2 0 2\nv 2 0 -2\nf 1 2 3\nf 1 3 4\no platform\nv -0.5 0.5 -0.5\nv -0.5 0.5 0.5\nv 0.5 0.5 0.5\nv 0.5 0.5 -0.5\nf 5 6 7\nf 5 7 8\nf 5 5 6\n";

#[test]
fn mesh_files_are_read_and_bad_ones_named() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "platform.obj", PLATFORM_OBJ);
    let scene = write(
        dir.path(),
        "s.toml",
        "[scene]\nframes = 2\nwidth = 64\nheight = 48\n[geometry]\nmesh = \"platform.obj\"\n[snow]\nmap_resolution = 32\ndirections = 8\nshadow_resolution = 64\n",
    );
    let out = crate::run(dir.path(), &["render", &scene, "--out", "o"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("skipped 1 degenerate triangle(s)"), "{stderr}");
    assert_eq!(std::fs::read_dir(dir.path().join("o")).unwrap().count(), 2);
    ok(dir.path(), &["export", "snow-mesh", &scene, "--format", "obj", "--out", "m.obj"]);

    let missing =
        write(dir.path(), "m.toml", "[scene]\nframes = 1\n[geometry]\nmesh = \"nope.obj\"\n[snow]\n");
    let err = fails(dir.path(), &["render", &missing, "--out", "o2"]);
    assert!(err.contains("m.toml:4:8: geometry.mesh = \"nope.obj\": no such file"), "{err}");
    write(dir.path(), "bad.glb", "glTF garbage");
    let corrupt =
        write(dir.path(), "c.toml", "[scene]\nframes = 1\n[geometry]\nmesh = \"bad.glb\"\n[snow]\n");
    let err = fails(dir.path(), &["render", &corrupt, "--out", "o3"]);
    assert!(err.contains("bad.glb") && err.contains("not a valid glTF file"), "{err}");
    write(dir.path(), "x.stl", "solid");
    let unknown = write(dir.path(), "u.toml", "[scene]\nframes = 1\n[geometry]\nmesh = \"x.stl\"\n[snow]\n");
    let err = fails(dir.path(), &["render", &unknown, "--out", "o4"]);
    assert!(err.contains("unknown mesh format `.stl`"), "{err}");
    write(dir.path(), "empty.obj", "# nothing here\n");
    let empty =
        write(dir.path(), "e.toml", "[scene]\nframes = 1\n[geometry]\nmesh = \"empty.obj\"\n[snow]\n");
    let err = fails(dir.path(), &["render", &empty, "--out", "o5"]);
    assert!(err.contains("empty.obj") && err.contains("no usable triangle"), "{err}");
}
