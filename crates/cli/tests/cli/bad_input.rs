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

/// Scenes that were accepted but would do something questionable get an
/// error at the key that causes it (items 6 and 8).
#[test]
fn questionable_scenes_are_refused_at_their_keys() {
    let dir = tempfile::tempdir().unwrap();
    let head = "[scene]\nframes = 2\nwidth = 32\nheight = 18\n";
    let line = |z: f32| format!("[[0.0, {z}], [100.0, {z}], [200.0, {z}]]");
    let two_keyframes = format!(
        "[[aurora.keyframes]]\nframe = 0\nsheets = [{}]\n[[aurora.keyframes]]\nframe = 10\nsheets = [{}]\n",
        line(100.0),
        line(120.0)
    );
    let cases: Vec<(String, &str)> = vec![
        // Snow: a group list that does not cover the objects; a mesh and a built-in scene.
        (
            format!("{head}[geometry]\nbuiltin = \"primitives\"\n[snow]\nobject_groups = []\n"),
            "8:17: snow.object_groups = 0 entries: expected one group number per object of the scene: 5 entries",
        ),
        (
            format!("{head}[geometry]\nbuiltin = \"table\"\nmesh = \"yard.obj\"\n[snow]\n"),
            "7:8: geometry.mesh = \"yard.obj\": expected either a mesh file or builtin = \"table\", not both",
        ),
        // Aurora: no sheets; a merge of a point with itself; a split listed twice; a
        // keyframe past what f32 frames count exactly.
        (
            format!(
                "{head}[[aurora.keyframes]]\nframe = 0\nsheets = []\n[[aurora.keyframes]]\nframe = 10\nsheets = []\n"
            ),
            "aurora.keyframes[0].sheets: the keyframes have no sheets",
        ),
        (
            format!(
                "{head}{two_keyframes}[[aurora.merges]]\nkeyframe = 1\na = {{ sheet = 0, point = 31 }}\nb = {{ sheet = 0, point = 31 }}\n"
            ),
            "aurora.merges[0]: merge 0 joins sheet 0 point 31 with itself",
        ),
        (
            format!(
                "{head}{two_keyframes}[[aurora.splits]]\nkeyframe = 1\nstart = {{ sheet = 0, point = 3 }}\n[[aurora.splits]]\nkeyframe = 1\nstart = {{ sheet = 0, point = 3 }}\n"
            ),
            "aurora.splits[1]: split 1 repeats split 0",
        ),
        (
            format!("{head}{}", two_keyframes.replace("frame = 10", "frame = 4294967295")),
            "aurora.keyframes[1].frame = 4294967295: expected an integer in [0, 16777216]",
        ),
    ];
    for (k, (text, expect)) in cases.iter().enumerate() {
        let scene = write(dir.path(), &format!("q{k}.toml"), text);
        let e = fails(dir.path(), &["validate", &scene]);
        assert!(e.contains(&format!("q{k}.toml:")) && e.contains(expect), "case {k}: {e}");
    }
}

/// `validate` builds no simulation, so a scene whose work runs away
/// is checked at once; a scene over the memory budget is refused by `validate` and
/// `render` alike, with the estimate and the flag that raises the budget.
#[test]
fn validate_is_quick_and_the_memory_budget_holds() {
    let dir = tempfile::tempdir().unwrap();
    let runaway = write(
        dir.path(),
        "runaway.toml",
        "[scene]\nframes = 3\nwidth = 64\nheight = 36\n[geometry]\nbuiltin = \"table\"\n[snow]\ndirections = 4096\nmap_resolution = 4096\n",
    );
    let out = assert_cmd::cargo::cargo_bin_cmd!("phenomena")
        .current_dir(dir.path())
        .args(["validate", &runaway])
        .timeout(std::time::Duration::from_secs(60))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("runaway.toml: ok (snow scene") && stdout.contains("GiB of memory"), "{stdout}");
    // 8192² depth maps, one per worker thread: over a 1 GiB budget.
    let deep = write(
        dir.path(),
        "deep.toml",
        "[scene]\nframes = 3\nwidth = 64\nheight = 36\n[geometry]\nbuiltin = \"table\"\n[snow]\nshadow_resolution = 8192\n",
    );
    for args in [vec!["validate", &deep], vec!["render", &deep, "--out", "o"]] {
        let mut args: Vec<&str> = args;
        args.extend(["--max-memory-gib", "0.5", "--threads", "1"].iter().take(if args[0] == "render" {
            4
        } else {
            2
        }));
        let e = fails(dir.path(), &args);
        assert!(
            e.contains("more than the budget of 0.50 GiB") && e.contains("--max-memory-gib"),
            "{args:?}: {e}"
        );
    }
    assert!(!dir.path().join("o").join("frame_00000.png").exists(), "nothing rendered over the budget");
    let out = run(dir.path(), &["validate", &deep, "--max-memory-gib", "-1"]);
    assert_eq!(out.status.code(), Some(2), "a budget must be positive");
}

/// `validate` and `render` check a scene by one path: a problem found when the scene is
/// built (an `object_groups` that does not fit the mesh, a sparkle cone with too many
/// candidates) is located at its key by both, also when the command line overrides the
/// size or the view.
#[test]
fn render_locates_what_validate_locates() {
    let dir = tempfile::tempdir().unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let snow = std::fs::read_to_string(root.join("snow-table.toml"))
        .unwrap()
        .replace("[snow]\n", "[snow]\nobject_groups = []\n");
    let snow = write(dir.path(), "groups.toml", &snow);
    let sparkle = std::fs::read_to_string(root.join("sparkle-diamond-dust.toml"))
        .unwrap()
        .replace("exponent_n = 10000.0", "exponent_n = 2.0");
    let sparkle = write(dir.path(), "cone.toml", &sparkle);
    for (scene, at) in [
        (&snow, "groups.toml:19:17: snow.object_groups"),
        (&sparkle, "cone.toml:27:17: sparkle.phong.threshold_i_e"),
    ] {
        let v = fails(dir.path(), &["validate", scene]);
        assert!(v.contains(at), "validate: {v}");
        let r = fails(
            dir.path(),
            &["render", scene, "--out", "o", "--frames", "1", "--width", "64", "--height", "36"],
        );
        assert!(r.contains(at), "render: {r}");
    }
}

/// Every problem of a file is reported, also when one is a value that cannot be read at
/// all (a misspelt choice): the range problems of the rest come with it.
#[test]
fn a_bad_choice_does_not_hide_the_other_problems() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "two.toml",
        "[scene]\nframes = 0\n[flame]\nmode = \"paperr\"\n[flame.emitter]\nrate_per_s = -5.0\n",
    );
    let e = fails(dir.path(), &["validate", &scene]);
    assert!(e.contains("two.toml:2:10: scene.frames = 0"), "{e}");
    assert!(e.contains("two.toml:4:8: unknown variant `paperr`"), "{e}");
    assert!(e.contains("two.toml:6:14: flame.emitter.rate_per_s = -5"), "{e}");
}

/// An aurora whose source shape lies wholly outside the plane would render black frames
/// (the particles are born on it): refused at the keyframe, with the plane's extent.
#[test]
fn an_aurora_that_cannot_show_anything_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "away.toml",
        "[scene]\nframes = 20\n[aurora]\n[[aurora.keyframes]]\nframe = 0\nsheets = [[[-5000.0, 200.0], [-4000.0, 160.0]]]\n[[aurora.keyframes]]\nframe = 10\nsheets = [[[60.0, 200.0], [300.0, 250.0]]]\n",
    );
    let e = fails(dir.path(), &["validate", &scene]);
    assert!(e.contains("away.toml:6:10: aurora.keyframes[0].sheets") && e.contains("[0, 400]"), "{e}");
}
