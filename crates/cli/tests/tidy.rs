//! Invariants of the source tree that no compiler checks (rust-analyzer's `tidy.rs`
//! habit): what the library crates never do, that the scene crate's modules form no
//! cycle, that every source file is on the map in ARCHITECTURE.md, that every
//! dependency is used, that no function outgrows a screen, that nothing stray sits at
//! the root, and that every phenomenon, format and shipped scene is registered. The
//! crates come from `cargo metadata`, never from a list kept here.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").canonicalize().unwrap()
}

/// A workspace crate as `cargo metadata` describes it.
struct Package {
    name: String,
    dir: PathBuf,
    /// (dependency as written in Cargo.toml, its kind: "normal", "dev" or "build").
    deps: Vec<(String, String)>,
    /// Why it may do IO (`[package.metadata.tidy] io = "..."`); `None`: a pure library.
    io: Option<String>,
}

/// Every crate of the workspace.
fn workspace() -> Vec<Package> {
    let out = Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--no-deps", "--offline"])
        .current_dir(root())
        .output()
        .expect("cargo metadata runs");
    assert!(out.status.success(), "cargo metadata: {}", String::from_utf8_lossy(&out.stderr));
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    meta["packages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| Package {
            name: p["name"].as_str().unwrap().to_string(),
            dir: Path::new(p["manifest_path"].as_str().unwrap()).parent().unwrap().to_path_buf(),
            deps: p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| {
                    let name = d["rename"].as_str().or(d["name"].as_str()).unwrap().to_string();
                    (name, d["kind"].as_str().unwrap_or("normal").to_string())
                })
                .collect(),
            io: p["metadata"]["tidy"]["io"].as_str().map(str::to_string),
        })
        .collect()
}

/// Every `.rs` file under `dir`, recursively, sorted (none if `dir` is missing).
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else { continue };
        for entry in entries {
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
/// must not use) and without its `#[cfg(test)] mod tests` (tests may use anything).
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let text = text.split("#[cfg(test)]\nmod tests").next().unwrap_or("").to_string();
    text.lines().map(|l| l.split_once("//").map_or(l, |(code, _)| code)).collect::<Vec<_>>().join("\n")
}

/// Every path a file's `use` declarations bring in, their brace groups expanded:
/// `use std::{fs::File, io};` gives `std::fs::File` and `std::io`.
fn use_paths(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("use ") {
        let before = rest[..at].chars().last();
        rest = &rest[at + 4..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let Some(end) = rest.find(';') else { break };
        // Whitespace collapsed, and dropped beside the tree's punctuation (kept around
        // `as`).
        let mut tree = rest[..end].split_whitespace().collect::<Vec<_>>().join(" ");
        for p in ["{", "}", ",", "::"] {
            tree = tree.replace(&format!(" {p}"), p).replace(&format!("{p} "), p);
        }
        expand("", &tree, &mut out);
        rest = &rest[end..];
    }
    out
}

/// Expand one use tree under `prefix`.
fn expand(prefix: &str, tree: &str, out: &mut Vec<String>) {
    let join = |a: &str, b: &str| if a.is_empty() { b.to_string() } else { format!("{a}::{b}") };
    match tree.find('{') {
        Some(open) if tree.ends_with('}') => {
            let head = tree[..open].trim_end_matches("::");
            let inner = &tree[open + 1..tree.len() - 1];
            let base = join(prefix, head);
            let mut depth = 0;
            let mut start = 0;
            for (i, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        expand(&base, &inner[start..i], out);
                        start = i + 1;
                    }
                    _ => {}
                }
            }
            expand(&base, &inner[start..], out);
        }
        _ if !tree.is_empty() => out.push(join(prefix, tree.split(" as ").next().unwrap_or(tree))),
        _ => {}
    }
}

/// Whether `code` holds `word` as a whole word (not inside a longer identifier).
fn has_word(code: &str, word: &str) -> bool {
    let ident = |c: char| c.is_alphanumeric() || c == '_';
    code.match_indices(word).any(|(i, _)| {
        let before = code[..i].chars().last();
        let after = code[i + word.len()..].chars().next();
        !before.is_some_and(ident) && !after.is_some_and(|c| ident(c) && !word.ends_with('!'))
    })
}

/// What a pure library's code never names (in `use` or written out), and why.
const FORBIDDEN_PATHS: [(&str, &str); 5] = [
    ("std::fs", "libraries do no file IO: files are read through phenomena-scene's Assets"),
    ("std::net", "libraries open no sockets"),
    (
        "std::time::Instant",
        "libraries read no clock: timings come from an injected phenomena_core::clock::Clock",
    ),
    ("std::time::SystemTime", "libraries read no clock"),
    ("std::io::stdout", "libraries never print"),
];

/// Macros a library never calls.
const FORBIDDEN_MACROS: [&str; 5] = ["println!", "eprintln!", "print!", "eprint!", "dbg!"];

/// The problems of `file` against the rules above; `files_ok` allows file IO.
fn impurities(file: &Path, files_ok: bool) -> Vec<String> {
    let code = code(file);
    let mut found = Vec::new();
    let written: Vec<String> = use_paths(&code);
    for (path, why) in FORBIDDEN_PATHS {
        if files_ok && path == "std::fs" {
            continue;
        }
        let imported = written.iter().any(|u| u == path || u.starts_with(&format!("{path}::")));
        if imported || code.contains(&format!("{path}::")) || has_word(&code, path) {
            found.push(format!("{}: `{path}`: {why}", file.display()));
        }
    }
    for m in FORBIDDEN_MACROS {
        if has_word(&code, m) {
            found.push(format!("{}: `{m}`: libraries never print", file.display()));
        }
    }
    found
}

#[test]
fn pure_library_crates_touch_no_files_clocks_or_terminals() {
    let mut found = Vec::new();
    let mut pure = 0;
    for p in workspace().iter().filter(|p| p.io.is_none()) {
        pure += 1;
        for file in rust_files(&p.dir.join("src")) {
            found.extend(impurities(&file, false));
        }
    }
    assert!(pure >= 5, "only {pure} crates are checked as pure libraries");
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn the_scene_crate_touches_files_only_in_assets_and_output_and_never_prints() {
    let mut found = Vec::new();
    for file in rust_files(&root().join("crates/scene/src")) {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        found.extend(impurities(&file, name == "assets.rs" || name == "output.rs"));
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}

/// The modules of a crate's `src` (file stem) and the crate modules each one's code
/// names (`crate::x`, `use crate::{x, ...}`).
fn module_graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let stems: BTreeSet<String> = rust_files(src)
        .iter()
        .filter(|f| f.parent() == Some(src))
        .map(|f| f.file_stem().unwrap().to_string_lossy().into_owned())
        .filter(|s| s != "lib")
        .collect();
    let mut graph = BTreeMap::new();
    for m in &stems {
        let code = code(&src.join(format!("{m}.rs")));
        let mut named: BTreeSet<String> = BTreeSet::new();
        for path in use_paths(&code) {
            if let Some(rest) = path.strip_prefix("crate::") {
                named.insert(rest.split("::").next().unwrap().to_string());
            }
        }
        for (i, _) in code.match_indices("crate::") {
            let rest = &code[i + 7..];
            let end = rest.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(rest.len());
            named.insert(rest[..end].to_string());
        }
        named.retain(|n| stems.contains(n) && n != m);
        graph.insert(m.clone(), named);
    }
    graph
}

/// A cycle through the graph, if there is one (depth-first search).
fn cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == node) {
            let mut c = path[at..].to_vec();
            c.push(node.to_string());
            return Some(c);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in &graph[node] {
            if let Some(c) = visit(next, graph, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph.keys().find_map(|n| visit(n, graph, &mut Vec::new(), &mut done))
}

/// Shared types live in leaf modules: the scene crate's modules, by what their code
/// names of each other (tests aside), form no cycle.
#[test]
fn the_scene_crate_has_no_import_cycle() {
    let graph = module_graph(&root().join("crates/scene/src"));
    assert!(graph.len() > 20, "the module graph was not read: {graph:?}");
    assert!(graph["runner"].contains("sink"), "the module graph misses known edges: {graph:?}");
    if let Some(c) = cycle(&graph) {
        panic!("crates/scene/src has an import cycle: {}", c.join(" -> "));
    }
}

/// ARCHITECTURE.md's code map has one paragraph per crate, opening with its path in
/// bold (`**`crates/core`** ...`, `**`python`** ...`); every source file of the crate is
/// named in it (a library's `lib.rs` excepted).
#[test]
fn every_source_file_is_on_the_map() {
    let map = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let mut sections: BTreeMap<String, String> = BTreeMap::new();
    let mut current: Option<String> = None;
    for line in map.lines() {
        if let Some(rest) = line.strip_prefix("**`") {
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
    for p in workspace() {
        let name = p.dir.strip_prefix(root()).unwrap_or(&p.dir).to_string_lossy().into_owned();
        let Some(section) = sections.get(&name) else {
            missing.push(format!("{name} has no paragraph in ARCHITECTURE.md's code map"));
            continue;
        };
        for file in rust_files(&p.dir.join("src")) {
            let file_name = file.file_name().unwrap().to_string_lossy().into_owned();
            if file_name == "lib.rs" {
                continue; // every library has one: its crate docs and re-exports
            }
            if !section.contains(&file_name) {
                missing.push(format!("{} is not named in the {name} paragraph", file.display()));
            }
        }
    }
    assert!(missing.is_empty(), "{}", missing.join("\n"));
}

/// Every dependency a crate declares is named in its code: a normal one in `src/`
/// (where the library or binary is built from), a dev-dependency anywhere in the crate.
#[test]
fn every_dependency_is_used() {
    let mut unused = Vec::new();
    for p in workspace() {
        let mut sources = rust_files(&p.dir.join("src"));
        let mut everything = sources.clone();
        for dir in ["tests", "benches", "examples"] {
            everything.extend(rust_files(&p.dir.join(dir)));
        }
        let read = |files: &mut Vec<PathBuf>| -> String {
            files.iter().map(|f| std::fs::read_to_string(f).unwrap()).collect::<Vec<_>>().join("\n")
        };
        let (src, all) = (read(&mut sources), read(&mut everything));
        for (dep, kind) in &p.deps {
            let ident = dep.replace('-', "_");
            let text = if kind == "dev" { &all } else { &src };
            let named = [format!("{ident}::"), format!("use {ident}"), format!("extern crate {ident}")]
                .iter()
                .any(|w| text.contains(w.as_str()));
            if !named {
                unused.push(format!("{}: {kind} dependency `{dep}` is never named", p.name));
            }
        }
    }
    assert!(unused.is_empty(), "{}", unused.join("\n"));
}

/// The root holds the workspace's files and its folders, nothing left over (a job log,
/// a scratch render).
#[test]
fn nothing_stray_at_the_root() {
    const ROOT: [&str; 15] = [
        ".cargo",
        ".ci",
        ".gitignore",
        "ARCHITECTURE.md",
        "Cargo.lock",
        "Cargo.toml",
        "README.md",
        "blender",
        "crates",
        "docs",
        "python",
        "rustfmt.toml",
        "scenes",
        "tests",
        "tools",
    ];
    let out = Command::new("git").args(["ls-files"]).current_dir(root()).output();
    let tracked: BTreeSet<String> = match out {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout)
            .lines()
            .map(|l| l.split('/').next().unwrap().to_string())
            .collect(),
        // Not a git checkout (an unpacked source archive): what is on disk, bar the
        // build folder.
        _ => std::fs::read_dir(root())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n != "target" && n != ".git")
            .collect(),
    };
    let stray: Vec<&String> = tracked.iter().filter(|t| !ROOT.contains(&t.as_str())).collect();
    assert!(stray.is_empty(), "stray files at the root: {stray:?}");
}

/// Every `impl Phenomenon for X` in the scene crate has its line in
/// `registry::PHENOMENA`, and every `impl OutputFormat for X` its line in
/// `registry::FORMATS`: nothing implemented is left out of the lists tools read.
#[test]
fn every_phenomenon_and_format_is_registered() {
    let src = root().join("crates/scene/src");
    let registry = std::fs::read_to_string(src.join("registry.rs")).unwrap();
    let mut missing = Vec::new();
    for file in rust_files(&src) {
        let module = file.file_stem().unwrap().to_string_lossy().into_owned();
        let code = code(&file);
        for (marker, line) in [
            ("impl Phenomenon for ", "Entry::of::<crate::{m}::{t}>()"),
            ("impl OutputFormat for ", "Format::new(&crate::{m}::{t})"),
        ] {
            for (i, _) in code.match_indices(marker) {
                let rest = &code[i + marker.len()..];
                let ty = rest.split(|c: char| !(c.is_alphanumeric() || c == '_')).next().unwrap();
                let want = line.replace("{m}", &module).replace("{t}", ty);
                if !registry.contains(&want) {
                    missing.push(format!("{}: `{want}` is not in registry.rs", file.display()));
                }
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

#[test]
fn use_trees_expand_and_words_are_whole() {
    let paths = use_paths("use std::{fs::File, io::{self, Read}};\nuse crate::x as y;\nfn f() { reuse(); }");
    assert_eq!(paths, ["std::fs::File", "std::io::self", "std::io::Read", "crate::x"]);
    assert!(has_word("a println!(x)", "println!") && !has_word("eprintln!(x)", "println!"));
    assert!(!has_word("my_std::fs::x", "std::fs"));
    let g = BTreeMap::from([
        ("a".to_string(), BTreeSet::from(["b".to_string()])),
        ("b".to_string(), BTreeSet::from(["a".to_string()])),
    ]);
    assert_eq!(cycle(&g), Some(vec!["a".to_string(), "b".to_string(), "a".to_string()]));
}

/// The functions of a file longer than `max` lines, counted from the line of `fn` to
/// the closing brace at the same indentation (name, first line, length).
fn long_functions(text: &str, max: usize) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut found = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = line.len() - trimmed.len();
        let mut words = trimmed.split_whitespace().skip_while(|w| {
            ["pub", "pub(crate)", "pub(super)", "const", "async", "unsafe", "extern"].contains(w)
        });
        if words.next() != Some("fn") {
            continue;
        }
        let name = words.next().unwrap_or("").split(['(', '<']).next().unwrap_or("").to_string();
        // The signature ends at the first line ending in `{` (a body) or `;` (none).
        let Some(open) = (i..lines.len()).find(|&j| {
            let l = lines[j].trim_end();
            l.ends_with('{') || l.ends_with(';')
        }) else {
            continue;
        };
        if lines[open].trim_end().ends_with(';') {
            continue;
        }
        let close = (open + 1..lines.len()).find(|&j| {
            let l = lines[j];
            l.len() - l.trim_start().len() == indent && l.trim_start().starts_with('}')
        });
        let length = close.map_or(lines.len(), |c| c + 1) - i;
        if length > max {
            found.push((name, i + 1, length));
        }
    }
    found
}

/// No function is longer than a screen (80 lines), in any crate, tests included.
#[test]
fn no_function_is_longer_than_80_lines() {
    let mut long = Vec::new();
    for p in workspace() {
        for dir in ["src", "tests", "benches", "examples"] {
            for file in rust_files(&p.dir.join(dir)) {
                let text = std::fs::read_to_string(&file).unwrap();
                for (name, line, length) in long_functions(&text, 80) {
                    long.push(format!("{}:{line}: fn {name} is {length} lines", file.display()));
                }
            }
        }
    }
    assert!(long.is_empty(), "{}", long.join("\n"));
}

/// `phenomena-core` holds what two or more crates share: each of its modules (a table
/// made for another core module aside) is named by at least two other crates.
#[test]
fn every_core_module_serves_two_crates() {
    let packages = workspace();
    let core = packages.iter().find(|p| p.name == "phenomena-core").expect("the core crate");
    let src = core.dir.join("src");
    let graph = module_graph(&src);
    let mut lonely = Vec::new();
    for module in graph.keys() {
        // Used inside the core by another of its modules: part of that one.
        if graph.iter().any(|(m, uses)| m != module && uses.contains(module)) {
            continue;
        }
        let users: Vec<&str> = packages
            .iter()
            .filter(|p| p.name != core.name)
            .filter(|p| {
                ["src", "tests", "benches", "examples"].iter().any(|d| {
                    rust_files(&p.dir.join(d)).iter().any(|f| {
                        let text = std::fs::read_to_string(f).unwrap();
                        use_paths(&text).iter().any(|u| u.starts_with(&format!("phenomena_core::{module}")))
                            || text.contains(&format!("phenomena_core::{module}::"))
                    })
                })
            })
            .map(|p| p.name.as_str())
            .collect();
        if users.len() < 2 {
            lonely.push(format!("phenomena_core::{module} is used by {users:?}: it belongs in its one user"));
        }
    }
    assert!(lonely.is_empty(), "{}", lonely.join("\n"));
}

#[test]
fn long_functions_are_measured_from_fn_to_its_brace() {
    let text = "fn short() {\n    1\n}\n\n    pub(crate) fn long(\n        x: u32,\n    ) -> u32 {\n        x\n        + 1\n    }\nfn decl();\n";
    assert_eq!(long_functions(text, 3), vec![("long".to_string(), 5, 6)]);
    assert!(long_functions(text, 6).is_empty());
}
