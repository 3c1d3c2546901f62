//! The README's quick start runs as written: every `phenomena` command in its shell
//! blocks, in a folder holding the shipped scenes, succeeds and writes what the README
//! says it writes.

use std::path::Path;

use crate::run;

/// The `phenomena ...` lines of the shell blocks in the README's "Quick start" section.
fn quick_start_commands() -> Vec<String> {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../README.md")).unwrap();
    let start = readme.find("## Quick start").expect("the README has a quick start");
    let section = &readme[start..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    let mut commands = Vec::new();
    let mut in_block = false;
    for line in section.lines() {
        if line.starts_with("```") {
            in_block = line == "```sh";
            continue;
        }
        if in_block && line.starts_with("phenomena ") {
            commands.push(line.to_string());
        }
    }
    commands
}

#[test]
fn the_quick_start_runs_as_written() {
    let commands = quick_start_commands();
    assert!(commands.len() >= 4, "{commands:?}");
    let dir = tempfile::tempdir().unwrap();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    std::os::unix::fs::symlink(scenes, dir.path().join("scenes")).unwrap();
    for command in &commands {
        let args: Vec<&str> = command.split_whitespace().skip(1).collect();
        let out = run(dir.path(), &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        if args[0] == "studio" {
            // This test binary is built without the studio: the command exists and says
            // how to get it.
            assert!(stderr.contains("--features studio"), "{command}: {stderr}");
            continue;
        }
        assert!(out.status.success(), "{command} failed:\n{stderr}");
    }
    // What the README says the renders write.
    for frame in ["out/fire/frame_00060.png", "out/fire/frame_00071.png", "out/aurora/frame_00061.png"] {
        assert!(dir.path().join(frame).is_file(), "{frame} missing");
    }
    assert!(!dir.path().join("out/fire/frame_00059.png").exists(), "earlier frames are not written");
}
