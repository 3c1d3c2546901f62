//! Invariants of the source tree that no compiler checks (rust-analyzer's `tidy.rs`
//! habit): what the library crates never do, that every source file is on the map in
//! ARCHITECTURE.md, and that every shipped scene is registered and valid.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every `.rs` file under `dir`, recursively, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display())) {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// The code of a file without its `//` comments (doc comments may name what the code
/// must not use).
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines().map(|l| l.split_once("//").map_or(l, |(code, _)| code)).collect::<Vec<_>>().join("\n")
}

const LIBRARIES: [&str; 5] = ["core", "flame", "aurora", "snow", "sparkle"];

/// What no library crate's source contains, and why.
const FORBIDDEN: [(&str, &str); 8] = [
    ("std::fs", "libraries do no file IO: files are read through phenomena-scene's Assets"),
    ("File::", "libraries do no file IO"),
    ("Instant", "libraries read no clock: timings come from an injected phenomena_core::clock::Clock"),
    ("SystemTime", "libraries read no clock"),
    ("println!", "libraries never print"),
    ("eprintln!", "libraries never print"),
    ("print!", "libraries never print"),
    ("dbg!", "libraries never print"),
];

#[test]
fn library_crates_touch_no_files_clocks_or_terminals() {
    let mut found = Vec::new();
    for krate in LIBRARIES {
        for file in rust_files(&root().join("crates").join(krate).join("src")) {
            let code = code(&file);
            for (word, why) in FORBIDDEN {
                if code.contains(word) {
                    found.push(format!("{}: `{word}`: {why}", file.display()));
                }
            }
        }
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn the_scene_crate_touches_files_only_in_assets_and_output_and_never_prints() {
    let mut found = Vec::new();
    for file in rust_files(&root().join("crates/scene/src")) {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let code = code(&file);
        for (word, why) in FORBIDDEN {
            let file_io = word == "std::fs" || word == "File::";
            if code.contains(word) && !(file_io && (name == "assets.rs" || name == "output.rs")) {
                found.push(format!("{}: `{word}`: {why}", file.display()));
            }
        }
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}

/// ARCHITECTURE.md's code map has one paragraph per crate, opening with its path in
/// bold (`**`crates/core`** ...`); every source file of the crate is named in it (a
/// library's `lib.rs` excepted).
#[test]
fn every_source_file_is_on_the_map() {
    let map = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let mut sections: BTreeMap<String, String> = BTreeMap::new();
    let mut current: Option<String> = None;
    for line in map.lines() {
        if let Some(rest) = line.strip_prefix("**`crates/") {
            let name = rest.split('`').next().unwrap().to_string();
            current = Some(name.clone());
            sections.insert(name, String::new());
        } else if line.starts_with('#') {
            current = None;
        }
        if let Some(c) = &current {
            let s = sections.get_mut(c).unwrap();
            s.push_str(line);
            s.push('\n');
        }
    }
    let mut missing = Vec::new();
    for entry in std::fs::read_dir(root().join("crates")).unwrap() {
        let krate = entry.unwrap().path();
        let name = krate.file_name().unwrap().to_string_lossy().into_owned();
        let Some(section) = sections.get(&name) else {
            missing.push(format!("crates/{name} has no paragraph in ARCHITECTURE.md's code map"));
            continue;
        };
        let src = krate.join("src");
        for file in rust_files(&src) {
            let file_name = file.file_name().unwrap().to_string_lossy().into_owned();
            if file_name == "lib.rs" && name != "sph-peer" {
                continue; // every library has one: its crate docs and re-exports
            }
            if !section.contains(&format!("`{file_name}`")) && !section.contains(&file_name) {
                missing.push(format!("{} is not named in the crates/{name} paragraph", file.display()));
            }
        }
    }
    assert!(missing.is_empty(), "{}", missing.join("\n"));
}

#[test]
fn every_shipped_scene_is_registered_and_validates() {
    let dir = root().join("scenes");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f.ends_with(".toml"))
        .collect();
    files.sort();
    let mut listed: Vec<String> =
        phenomena_scene::shipped::SHIPPED.iter().map(|s| format!("{}.toml", s.name)).collect();
    listed.sort();
    assert_eq!(files, listed, "scenes/ and phenomena_scene::shipped::SHIPPED differ");
    for s in phenomena_scene::shipped::SHIPPED.iter() {
        // The file on disk, not only the embedded copy, validates.
        let scene =
            phenomena_scene::load(&dir.join(format!("{}.toml", s.name))).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(scene.phenomenon().name(), s.phenomenon, "{}", s.name);
    }
}
