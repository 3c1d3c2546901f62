//! End-to-end tests of the `phenomena` binary: one scenario per module, all through the
//! helpers below (run the binary, check its exit, its output and the files it wrote).

mod assets;
mod aurora_sky;
mod bad_input;
mod checkpoints;
mod determinism;
mod export_blackbody;
mod exports;
mod farm;
mod new_and_demo;
mod outputs;
mod readme;
mod render_frames;
mod resume;
mod shipped_scenes;
mod snow;
mod sparkle;

use std::path::Path;
use std::process::Output;

/// Run `phenomena` with `args` in `dir`.
pub fn run(dir: &Path, args: &[&str]) -> Output {
    assert_cmd::cargo::cargo_bin_cmd!("phenomena").current_dir(dir).args(args).output().expect("binary runs")
}

/// Run and require success; returns standard output.
pub fn ok(dir: &Path, args: &[&str]) -> String {
    let out = run(dir, args);
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "phenomena {args:?} failed:\n{stdout}\n{stderr}");
    stdout.into_owned()
}

/// Run and require a clean failure (exit 1, no panic); returns standard error.
pub fn fails(dir: &Path, args: &[&str]) -> String {
    let out = run(dir, args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "phenomena {args:?} should fail cleanly, stderr:\n{stderr}");
    assert!(!stderr.contains("panicked"), "phenomena {args:?} panicked:\n{stderr}");
    stderr
}

/// A small, quick flame scene (few particles, small frames).
pub const TINY_FLAME: &str = r#"
[scene]
frames = 4
width = 64
height = 36
seed = 3

[flame]
[flame.emitter]
rate_per_s = 1200.0
"#;

/// Write `text` to `dir/name` and return the path as a string.
pub fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write test file");
    p.to_string_lossy().into_owned()
}

/// PNG dimensions, read back with the `image` crate's format (via the header bytes).
pub fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).expect("png exists");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{} is not a PNG", path.display());
    let w = u32::from_be_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]);
    let h = u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]);
    (w, h)
}
