//! `--resume` keeps finished frames and writes only the missing ones.

use crate::{TINY_FLAME, ok, write};

#[test]
fn resume_skips_finished_frames() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    ok(dir.path(), &["render", &scene, "--out", "o"]);
    let o = dir.path().join("o");
    let original_2 = std::fs::read(o.join("frame_00002.png")).unwrap();
    // Frame 1 "finished" with a marker (to see that it is kept); frame 2 lost.
    std::fs::write(o.join("frame_00001.png"), b"kept").unwrap();
    std::fs::remove_file(o.join("frame_00002.png")).unwrap();
    let stdout = ok(dir.path(), &["render", &scene, "--out", "o", "--resume", "--stats", "s.jsonl"]);
    assert!(stdout.contains("wrote 1 frame(s), kept 3 finished frame(s)"), "{stdout}");
    assert_eq!(std::fs::read(o.join("frame_00001.png")).unwrap(), b"kept");
    // The re-rendered frame equals the original: the simulation ran through the skipped
    // frames to reach the same state.
    assert_eq!(std::fs::read(o.join("frame_00002.png")).unwrap(), original_2);
    let stats = std::fs::read_to_string(dir.path().join("s.jsonl")).unwrap();
    assert_eq!(stats.matches("\"skipped\":true").count(), 3);
    // No temporary files are left behind.
    assert!(
        std::fs::read_dir(&o).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".tmp"))
    );
}

/// SIGTERM (what `timeout` and container runtimes send) stops a render
/// between frames: exit status 1 with a message, every written frame whole, no
/// temporary file left; `--resume` then finishes with the same bytes as a render that
/// was never stopped.
#[cfg(unix)]
#[test]
fn sigterm_stops_between_frames_and_resume_finishes_the_same_bytes() {
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().unwrap();
    let text = TINY_FLAME
        .replace("frames = 4", "frames = 300")
        .replace("width = 64\nheight = 36", "width = 256\nheight = 144");
    let scene = write(dir.path(), "long.toml", &text);
    let frames = |d: &str| -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir.path().join(d))
            .map(|r| r.map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect())
            .unwrap_or_default();
        names.sort();
        names
    };
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_phenomena"))
        .current_dir(dir.path())
        .args(["render", &scene, "--out", "cut", "--format", "exr"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while frames("cut").iter().filter(|f| f.starts_with("frame_")).count() < 3 {
        assert!(child.try_wait().unwrap().is_none(), "the render ended before it was signalled");
        assert!(start.elapsed() < Duration::from_secs(120), "no frames within 120 s");
        std::thread::sleep(Duration::from_millis(5));
    }
    let killed = std::process::Command::new("kill").args(["-TERM", &child.id().to_string()]).status();
    assert!(killed.unwrap().success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("interrupted by a signal") && stderr.contains("--resume"), "{stderr}");
    let cut = frames("cut");
    assert!(cut.iter().all(|f| f.starts_with("frame_") && f.ends_with(".exr")), "left behind: {cut:?}");
    assert!(cut.len() < 300, "the render was not stopped: {} frames", cut.len());
    ok(dir.path(), &["render", &scene, "--out", "cut", "--format", "exr", "--resume"]);
    ok(dir.path(), &["render", &scene, "--out", "whole", "--format", "exr"]);
    assert_eq!(frames("cut"), frames("whole"));
    for f in frames("whole") {
        let (a, b) = (
            std::fs::read(dir.path().join("cut").join(&f)),
            std::fs::read(dir.path().join("whole").join(&f)),
        );
        assert!(a.unwrap() == b.unwrap(), "{f} differs after the resume");
    }
}

/// A volume's manifest is written before the volume: a frame whose `.vdb` has no
/// `.vdb.json` beside it (a failure between the two) is not finished, and `--resume`
/// writes it again, volume and manifest.
#[test]
fn a_volume_without_its_manifest_is_written_again() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    ok(dir.path(), &["render", &scene, "--out", "v", "--format", "vdb"]);
    let v = dir.path().join("v");
    let manifest = std::fs::read(v.join("frame_00002.vdb.json")).unwrap();
    std::fs::remove_file(v.join("frame_00002.vdb.json")).unwrap();
    // A manifest alone (the volume lost) is not finished either.
    std::fs::remove_file(v.join("frame_00003.vdb")).unwrap();
    let stdout = ok(dir.path(), &["render", &scene, "--out", "v", "--format", "vdb", "--resume"]);
    assert!(stdout.contains("wrote 2 frame(s), kept 2 finished frame(s)"), "{stdout}");
    assert_eq!(std::fs::read(v.join("frame_00002.vdb.json")).unwrap(), manifest);
    assert!(v.join("frame_00003.vdb").is_file());
}
