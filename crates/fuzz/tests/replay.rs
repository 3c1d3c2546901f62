//! The fuzzers' corpus, replayed: every input AFL++ kept (each reached new code) runs
//! through its target again, so a change that makes any of them panic fails here. The
//! inputs are in `crates/fuzz/corpus/<target>/`.

use std::path::Path;

fn replay(target: &str, run: fn(&[u8])) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("corpus").join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no corpus for {target}");
    for file in files {
        let data = std::fs::read(&file).unwrap();
        let outcome = std::panic::catch_unwind(|| run(&data));
        assert!(outcome.is_ok(), "{target}: {} panics", file.display());
    }
}

#[test]
fn scene_corpus() {
    replay("scene", phenomena_fuzz::scene);
}

#[test]
fn obj_corpus() {
    replay("obj", phenomena_fuzz::obj);
}

#[test]
fn gltf_corpus() {
    replay("gltf", phenomena_fuzz::gltf);
}

#[test]
fn dxf_corpus() {
    replay("dxf", phenomena_fuzz::dxf);
}

#[test]
fn studio_corpus() {
    replay("studio", phenomena_fuzz::studio);
}

#[test]
fn checkpoint_corpus() {
    replay("checkpoint", phenomena_fuzz::checkpoint);
}

#[test]
fn air_corpus() {
    replay("air", phenomena_fuzz::air);
}
