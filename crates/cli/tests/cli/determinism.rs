//! The same scene and seed give byte-identical PNGs with one thread and with two.

use crate::{ok, write};

#[test]
fn one_and_two_threads_write_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "flame.toml",
        "[scene]\nframes = 20\nwidth = 160\nheight = 90\nseed = 9\n[flame]\n[flame.emitter]\nrate_per_s = 6000.0\n[render]\nresolution_scale = 0.5\n",
    );
    ok(dir.path(), &["render", &scene, "--out", "t1", "--threads", "1", "--frames", "15..20"]);
    ok(dir.path(), &["render", &scene, "--out", "t2", "--threads", "2", "--frames", "15..20"]);
    for f in 15..20 {
        let name = format!("frame_{f:05}.png");
        let a = std::fs::read(dir.path().join("t1").join(&name)).unwrap();
        let b = std::fs::read(dir.path().join("t2").join(&name)).unwrap();
        assert!(a == b, "{name} differs between 1 and 2 threads");
    }
    // EXR too: one writer thread, blocks in order.
    ok(dir.path(), &["render", &scene, "--out", "e1", "--threads", "1", "--frames", "19", "--format", "exr"]);
    ok(dir.path(), &["render", &scene, "--out", "e2", "--threads", "2", "--frames", "19", "--format", "exr"]);
    let a = std::fs::read(dir.path().join("e1/frame_00019.exr")).unwrap();
    let b = std::fs::read(dir.path().join("e2/frame_00019.exr")).unwrap();
    assert!(a == b, "EXR differs between 1 and 2 threads");
    // And a different seed gives a different image.
    ok(dir.path(), &["render", &scene, "--out", "s", "--seed", "10", "--frames", "19"]);
    let a = std::fs::read(dir.path().join("t1/frame_00019.png")).unwrap();
    let c = std::fs::read(dir.path().join("s/frame_00019.png")).unwrap();
    assert!(a != c);
}
