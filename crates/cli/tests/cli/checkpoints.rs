//! Checkpoints. Frames rendered in chunks from checkpoints, in any order, are
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

/// What is not a regular checkpoint file is refused without being read whole, and the
/// render falls back with a message: a FIFO (it hung the render), a symlink to
/// `/dev/zero` (read until memory ran out) and a sparse file of 1.5 GiB whose header is
/// not a checkpoint's.
#[test]
fn checkpoints_are_read_as_regular_files_header_first_within_the_budget() {
    let dir = tempfile::tempdir().unwrap();
    let text = TINY_FLAME.replace("frames = 4", "frames = 12");
    let scene = write(dir.path(), "tiny.toml", &text);
    ok(dir.path(), &["render", &scene, "--out", "whole", "--checkpoint-every", "4"]);
    let whole = frames(&dir.path().join("whole"));
    let ck = dir.path().join("ck");
    std::fs::create_dir(&ck).unwrap();
    // Frame 4: the real checkpoint; 8: a FIFO; the render of 8..12 falls back to 4.
    std::fs::copy(
        dir.path().join("whole/checkpoints/checkpoint_00004.ckpt"),
        ck.join("checkpoint_00004.ckpt"),
    )
    .unwrap();
    let made = std::process::Command::new("mkfifo").arg(ck.join("checkpoint_00008.ckpt")).status().unwrap();
    assert!(made.success());
    let render = |out: &str, extra: &[&str]| {
        let mut args = vec!["render", &scene, "--out", out, "--frames", "8..12", "--checkpoint-dir", "ck"];
        args.extend_from_slice(extra);
        let out = run(dir.path(), &args);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        (String::from_utf8_lossy(&out.stdout).into_owned(), stderr)
    };
    let (stdout, stderr) = render("fifo", &[]);
    assert!(
        stderr.contains("checkpoint_00008.ckpt not used") && stderr.contains("not a regular file"),
        "{stderr}"
    );
    assert!(stdout.contains("started from the checkpoint at frame 4"), "{stdout}");
    assert_eq!(frames(&dir.path().join("fifo")), whole[8..]);

    std::fs::remove_file(ck.join("checkpoint_00008.ckpt")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", ck.join("checkpoint_00008.ckpt")).unwrap();
    let (_, stderr) = render("zero", &[]);
    assert!(stderr.contains("not a regular file"), "{stderr}");
    assert_eq!(frames(&dir.path().join("zero")), whole[8..]);

    // A sparse 1.5 GiB file takes no disk; only its first bytes may be read.
    std::fs::remove_file(ck.join("checkpoint_00008.ckpt")).unwrap();
    let sparse = std::fs::File::create(ck.join("checkpoint_00008.ckpt")).unwrap();
    sparse.set_len(3 << 29).unwrap();
    let (_, stderr) = render("sparse", &["--max-memory-gib", "1"]);
    assert!(stderr.contains("not a phenomena checkpoint"), "{stderr}");
    assert_eq!(frames(&dir.path().join("sparse")), whole[8..]);

    // (A real checkpoint over what the budget leaves: `output.rs` test
    // `checkpoints_are_refused_by_their_header_before_being_read`.)
    // A checkpoint folder that is a file is an error, not ignored.
    let e = crate::fails(
        dir.path(),
        &["render", &scene, "--out", "f", "--frames", "8..12", "--checkpoint-dir", "tiny.toml"],
    );
    assert!(e.contains("is a file, not a folder"), "{e}");
}

/// `[render.sky] afterglow = true` carries light from frame to frame: a render of frames
/// A..B, one resumed, and one offered checkpoints all render every frame from 0 (saying
/// so), and their frames equal the uninterrupted render's bytes.
#[test]
fn an_afterglow_is_rendered_from_frame_zero_and_equals_one_render() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "glow.toml",
        "[scene]\nframes = 8\nwidth = 64\nheight = 36\n[aurora]\n[aurora.motion]\nparticles = 3000\n[render.sky]\nafterglow = true\n",
    );
    ok(dir.path(), &["render", &scene, "--out", "whole", "--checkpoint-every", "4"]);
    let whole = frames(&dir.path().join("whole"));
    assert_eq!(whole.len(), 8);
    // The afterglow makes a frame depend on the ones before: rendering 5..8 without
    // frames 0..5 drawn would differ (checked: frame 5 of a render without afterglow).
    let out = run(
        dir.path(),
        &["render", &scene, "--out", "part", "--frames", "5..8", "--checkpoint-dir", "whole/checkpoints"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("afterglow") && stderr.contains("rendering every frame from 0"), "{stderr}");
    assert!(!String::from_utf8_lossy(&out.stdout).contains("started from the checkpoint"));
    assert_eq!(frames(&dir.path().join("part")), whole[5..]);
    std::fs::remove_file(dir.path().join("whole/frame_00006.png")).unwrap();
    ok(dir.path(), &["render", &scene, "--out", "whole", "--resume"]);
    assert_eq!(frames(&dir.path().join("whole")), whole);
    let plain = write(
        dir.path(),
        "plain.toml",
        &std::fs::read_to_string(&scene).unwrap().replace("afterglow = true", "afterglow = false"),
    );
    ok(dir.path(), &["render", &plain, "--out", "plain", "--frames", "5..6"]);
    assert_ne!(frames(&dir.path().join("plain"))[0], whole[5], "the afterglow changes frame 5");
}
