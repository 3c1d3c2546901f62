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
