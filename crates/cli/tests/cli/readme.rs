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
        if args[0] == "studio" {
            studio_starts(dir.path(), command, &args);
            continue;
        }
        let out = run(dir.path(), &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{command} failed:\n{stderr}");
    }
    // What the README says the renders write.
    for frame in ["out/fire/frame_00060.png", "out/fire/frame_00071.png", "out/aurora/frame_00061.png"] {
        assert!(dir.path().join(frame).is_file(), "{frame} missing");
    }
    assert!(!dir.path().join("out/fire/frame_00059.png").exists(), "earlier frames are not written");
}

/// Built without the studio, the command exists and says how to get it.
#[cfg(not(feature = "studio"))]
fn studio_starts(dir: &Path, command: &str, args: &[&str]) {
    let out = run(dir, args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--features studio"), "{command}: {stderr}");
}

/// Built with the studio (as CI builds it), the command serves its page: run on a free
/// port and without opening a browser, it prints the address it serves within a minute
/// and is stopped (also when the test fails: the guard kills it).
#[cfg(feature = "studio")]
fn studio_starts(dir: &Path, command: &str, args: &[&str]) {
    use std::io::{BufRead, BufReader};
    use std::process::{Child, Command, Stdio};
    use std::time::Duration;

    /// Kills the studio when dropped.
    struct Stop(Child);
    impl Drop for Stop {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }

    // The README's arguments without `--open` and any `--port N`, on a free port.
    let mut kept: Vec<&str> = Vec::new();
    let mut rest = args.iter().copied();
    while let Some(a) = rest.next() {
        match a {
            "--open" => {}
            "--port" => {
                rest.next();
            }
            _ if a.starts_with("--port=") => {}
            _ => kept.push(a),
        }
    }
    kept.extend(["--port", "0"]);
    let log = dir.join("studio-stderr.txt");
    let mut studio = Stop(
        Command::new(env!("CARGO_BIN_EXE_phenomena"))
            .args(&kept)
            .current_dir(dir)
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap(),
    );
    let stdout = studio.0.stdout.take().unwrap();
    let (send, receive) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut first = String::new();
        let _ = BufReader::new(stdout).read_line(&mut first);
        let _ = send.send(first);
    });
    let first = receive.recv_timeout(Duration::from_secs(60));
    drop(studio);
    let stderr = std::fs::read_to_string(&log).unwrap_or_default();
    let first =
        first.unwrap_or_else(|_| panic!("{command}: nothing on stdout within 60 s; stderr:\n{stderr}"));
    assert!(
        first.starts_with("phenomena studio: serving http://127.0.0.1:"),
        "{command}: {first:?}; stderr:\n{stderr}"
    );
}
