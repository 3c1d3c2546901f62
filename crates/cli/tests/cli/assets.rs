//! Files a scene names are read only as the glTF specification and the scene layer
//! allow: relative paths and `data:` URIs for glTF buffers, regular files only, and
//! every refusal located at the scene key that named the file.

use std::time::Duration;

use base64::Engine;

use crate::{ok, write};

/// One upward-facing 4 m triangle: three f32 (x, y, z) vertices.
fn triangle_bytes() -> Vec<u8> {
    [[0.0f32, 0.0, 0.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

/// A glTF whose only buffer has the URI `uri`.
fn gltf(uri: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","max":[4,0,4],"min":[0,0,0]}}],
"bufferViews":[{{"buffer":0,"byteLength":36}}],"buffers":[{{"uri":{uri:?},"byteLength":36}}]}}"#
    )
}

/// A small snow scene over `mesh`.
fn scene(mesh: &str) -> String {
    format!(
        "[scene]\nframes = 1\nwidth = 32\nheight = 24\n\n[geometry]\nmesh = {mesh:?}\n\n[snow]\nmap_resolution = 16\ndirections = 4\nshadow_resolution = 32\n"
    )
}

/// Run with a time limit: a FIFO must be refused at once, not waited on.
fn fails_quickly(dir: &std::path::Path, args: &[&str]) -> String {
    let out = assert_cmd::cargo::cargo_bin_cmd!("phenomena")
        .current_dir(dir)
        .args(args)
        .timeout(Duration::from_secs(60))
        .output()
        .expect("binary runs");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "phenomena {args:?} should fail cleanly:\n{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

#[test]
fn gltf_buffers_beside_the_file_above_it_or_inline_are_read() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    std::fs::write(dir.path().join("meshes/tri angle.bin"), triangle_bytes()).unwrap();
    std::fs::write(dir.path().join("shared.bin"), triangle_bytes()).unwrap();
    write(dir.path(), "meshes/beside.gltf", &gltf("tri%20angle.bin"));
    write(dir.path(), "meshes/above.gltf", &gltf("../shared.bin"));
    let inline = base64::engine::general_purpose::STANDARD.encode(triangle_bytes());
    write(dir.path(), "meshes/inline.gltf", &gltf(&format!("data:application/octet-stream;base64,{inline}")));
    for mesh in ["meshes/beside.gltf", "meshes/above.gltf", "meshes/inline.gltf"] {
        let s = write(dir.path(), "s.toml", &scene(mesh));
        ok(dir.path(), &["validate", &s]);
    }
}

#[test]
fn absolute_and_foreign_buffer_uris_are_refused_at_the_mesh_key() {
    let dir = tempfile::tempdir().unwrap();
    for (uri, why) in [
        ("/etc/hostname", "absolute paths are refused"),
        ("file:///etc/hostname", "only relative paths and data: URIs"),
        ("%2Fetc%2Fhostname", "absolute paths are refused"),
    ] {
        write(dir.path(), "m.gltf", &gltf(uri));
        let s = write(dir.path(), "s.toml", &scene("m.gltf"));
        let e = fails_quickly(dir.path(), &["validate", &s]);
        assert!(
            e.contains(&format!("s.toml:7:8: geometry.mesh = \"m.gltf\": its glTF buffer {uri:?}: ")),
            "{e}"
        );
        assert!(e.contains(why), "{uri}: {e}");
    }
}

#[cfg(unix)]
#[test]
fn devices_fifos_and_folders_are_refused_without_reading() {
    let dir = tempfile::tempdir().unwrap();
    let made = std::process::Command::new("mkfifo").arg(dir.path().join("pipe.bin")).status();
    assert!(made.expect("mkfifo runs").success());
    std::fs::create_dir(dir.path().join("folder.obj")).unwrap();
    let made = std::process::Command::new("mkfifo").arg(dir.path().join("pipe.obj")).status();
    assert!(made.expect("mkfifo runs").success());
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.obj")).unwrap();
    // The mesh itself: a device (through a symlink, which the command line follows), a
    // FIFO, a folder.
    for (mesh, why) in
        [("zero.obj", "not a regular file"), ("pipe.obj", "not a regular file"), ("folder.obj", "a folder")]
    {
        let s = write(dir.path(), "s.toml", &scene(mesh));
        let e = fails_quickly(dir.path(), &["render", &s, "--out", "o"]);
        assert!(e.contains(&format!("s.toml:7:8: geometry.mesh = {mesh:?}: {why}")), "{e}");
    }
    // A glTF buffer that is a FIFO or a device.
    for uri in ["pipe.bin", "../../../../../../../../dev/zero"] {
        write(dir.path(), "m.gltf", &gltf(uri));
        let s = write(dir.path(), "s.toml", &scene("m.gltf"));
        let e = fails_quickly(dir.path(), &["validate", &s]);
        assert!(e.contains(&format!("its glTF buffer {uri:?}: not a regular file")), "{e}");
    }
}
