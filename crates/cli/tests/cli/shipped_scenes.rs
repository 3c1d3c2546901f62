//! Every scene shipped in `scenes/` validates (shape crossings, splits and merges
//! included: `validate` builds the aurora's shapes).

use crate::ok;

#[test]
fn every_shipped_scene_validates() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut names: Vec<String> = std::fs::read_dir(root.join("scenes"))
        .expect("scenes/ exists")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    names.sort();
    assert!(names.len() >= 9, "flame and aurora scenes shipped: {names:?}");
    for name in &names {
        let out = ok(&root, &["validate", &format!("scenes/{name}")]);
        assert!(out.contains(": ok"), "{name}: {out}");
    }
}
