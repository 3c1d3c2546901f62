//! Issue 22: checkpoints. Frames rendered in chunks from checkpoints, in any order, are
//! byte-identical to one uninterrupted render, for every phenomenon; a damaged or
//! foreign checkpoint is refused with a message and the render falls back to an older
//! one or to simulating from frame 0, with the same bytes.

use std::path::Path;

use crate::{TINY_FLAME, ok, run, write};

/// Every file of `dir` whose name starts with `frame_`, sorted, with its bytes.
fn frames(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_name().to_string_lossy().starts_with("frame_"))
        .map(|e| (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).unwrap()))
        .collect();
    out.sort();
    out
}

/// Render `scene` whole (checkpoints every `every` frames), then each chunk of `every`
/// frames from the checkpoints, last chunk first, each into its own folder; every
/// chunk's frames must equal the whole render's.
fn chunks_equal_one_render(scene: &str, total: u32, every: u32, size: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(scene);
    let path = path.to_string_lossy().into_owned();
    let frames_arg = format!("0..{total}");
    let every_arg = every.to_string();
    let mut args =
        vec!["render", &path, "--out", "whole", "--frames", &frames_arg, "--checkpoint-every", &every_arg];
    args.extend_from_slice(size);
    ok(dir.path(), &args);
    let whole = frames(&dir.path().join("whole"));
    assert_eq!(whole.len(), total as usize);
    let ckpt = dir.path().join("whole/checkpoints");
    let ckpt = ckpt.to_string_lossy().into_owned();
    let starts: Vec<u32> = (0..total).step_by(every as usize).collect();
    for &a in starts.iter().rev() {
        let out = format!("chunk{a}");
        let range = format!("{a}..{}", (a + every).min(total));
        let mut args = vec!["render", &path, "--out", &out, "--frames", &range, "--checkpoint-dir", &ckpt];
        args.extend_from_slice(size);
        let stdout = ok(dir.path(), &args);
        if a > 0 {
            assert!(
                stdout.contains(&format!("started from the checkpoint at frame {a}")),
                "{scene}: {stdout}"
            );
        }
        for (name, bytes) in frames(&dir.path().join(&out)) {
            let reference = &whole.iter().find(|(n, _)| *n == name).unwrap().1;
            assert!(bytes == *reference, "{scene}: {name} rendered from a checkpoint differs");
        }
    }
}

#[test]
fn flame_chunks_from_checkpoints_equal_one_render() {
    chunks_equal_one_render("flame-paper.toml", 12, 4, &["--width", "96", "--height", "54"]);
}

#[test]
fn aurora_chunks_from_checkpoints_equal_one_render() {
    // Past the first renewal (every 5 frames in Table 3.3), so redistribution and a new
    // field are inside a chunk.
    chunks_equal_one_render("aurora-scene2.toml", 12, 4, &["--width", "96", "--height", "54"]);
}

#[test]
fn snow_chunks_from_checkpoints_equal_one_render() {
    chunks_equal_one_render("snow-table.toml", 9, 3, &["--width", "96", "--height", "54"]);
}

#[test]
fn sparkle_chunks_from_checkpoints_equal_one_render() {
    chunks_equal_one_render("sparkle-diamond-dust.toml", 9, 3, &["--width", "96", "--height", "54"]);
    chunks_equal_one_render("sparkle-leaf-glitter.toml", 6, 2, &["--width", "96", "--height", "54"]);
}

#[test]
fn damaged_or_foreign_checkpoints_are_refused_and_the_render_falls_back() {
    let dir = tempfile::tempdir().unwrap();
    let text = TINY_FLAME.replace("frames = 4", "frames = 9");
    let scene = write(dir.path(), "tiny.toml", &text);
    ok(dir.path(), &["render", &scene, "--out", "whole", "--checkpoint-every", "3"]);
    let whole = frames(&dir.path().join("whole"));
    let ck = dir.path().join("whole/checkpoints");
    let newest = ck.join("checkpoint_00006.ckpt");
    let bytes = std::fs::read(&newest).unwrap();

    // Truncated: refused, the older checkpoint at frame 3 is used, same bytes.
    std::fs::write(&newest, &bytes[..bytes.len() / 2]).unwrap();
    let out = run(
        dir.path(),
        &["render", &scene, "--out", "a", "--frames", "6..9", "--checkpoint-dir", "whole/checkpoints"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("checkpoint_00006.ckpt not used: the checkpoint is truncated"), "{stderr}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("started from the checkpoint at frame 3"));
    assert_eq!(frames(&dir.path().join("a")), whole[6..]);

    // One flipped byte: corrupt.
    let mut flipped = bytes.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 1;
    std::fs::write(&newest, &flipped).unwrap();
    std::fs::remove_file(ck.join("checkpoint_00003.ckpt")).unwrap();
    let out = run(
        dir.path(),
        &["render", &scene, "--out", "b", "--frames", "6..9", "--checkpoint-dir", "whole/checkpoints"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("the checkpoint is corrupt"), "{stderr}");
    assert!(stderr.contains("simulating from frame 0"), "{stderr}");
    assert_eq!(frames(&dir.path().join("b")), whole[6..]);

    // Another seed's checkpoint is another scene's.
    std::fs::write(&newest, &bytes).unwrap();
    let out = run(
        dir.path(),
        &[
            "render",
            &scene,
            "--out",
            "c",
            "--frames",
            "6..9",
            "--seed",
            "4",
            "--checkpoint-dir",
            "whole/checkpoints",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("belongs to another scene: it was made with seed 3"), "{stderr}");
    assert!(out.status.success());

    // Another physics: refused too.
    let hotter = write(dir.path(), "hot.toml", &text.replace("rate_per_s = 1200.0", "rate_per_s = 1300.0"));
    let out = run(
        dir.path(),
        &["render", &hotter, "--out", "d", "--frames", "6..9", "--checkpoint-dir", "whole/checkpoints"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("simulation settings"), "{stderr}");

    // Not a checkpoint at all.
    std::fs::write(&newest, b"hello").unwrap();
    let out = run(
        dir.path(),
        &["render", &scene, "--out", "e", "--frames", "6..9", "--checkpoint-dir", "whole/checkpoints"],
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a phenomena checkpoint"));
    assert_eq!(frames(&dir.path().join("e")), whole[6..]);
}

#[test]
fn a_checkpoint_serves_other_sizes_and_resume() {
    let dir = tempfile::tempdir().unwrap();
    let text = TINY_FLAME.replace("frames = 4", "frames = 8");
    let scene = write(dir.path(), "tiny.toml", &text);
    ok(dir.path(), &["simulate", &scene, "--checkpoint-every", "4", "--checkpoint-dir", "ck"]);
    assert!(dir.path().join("ck/checkpoint_00004.ckpt").is_file());
    assert!(dir.path().join("ck/checkpoint_00008.ckpt").is_file());
    // The frame size is not part of the simulation: a larger render starts at frame 4.
    let big = ok(
        dir.path(),
        &[
            "render",
            &scene,
            "--out",
            "big",
            "--frames",
            "4..8",
            "--width",
            "128",
            "--height",
            "72",
            "--checkpoint-dir",
            "ck",
        ],
    );
    assert!(big.contains("started from the checkpoint at frame 4"), "{big}");
    ok(dir.path(), &["render", &scene, "--out", "ref", "--width", "128", "--height", "72"]);
    assert_eq!(frames(&dir.path().join("big")), frames(&dir.path().join("ref"))[4..]);
    // --resume starts at the first missing frame from the checkpoint before it.
    std::fs::remove_file(dir.path().join("ref/frame_00006.png")).unwrap();
    std::fs::remove_file(dir.path().join("ref/frame_00007.png")).unwrap();
    let resumed = ok(
        dir.path(),
        &[
            "render",
            &scene,
            "--out",
            "ref",
            "--width",
            "128",
            "--height",
            "72",
            "--resume",
            "--checkpoint-dir",
            "ck",
        ],
    );
    assert!(resumed.contains("kept 6 finished frame(s)") && resumed.contains("at frame 4"), "{resumed}");
    assert_eq!(frames(&dir.path().join("ref"))[4..], frames(&dir.path().join("big"))[..]);
}
