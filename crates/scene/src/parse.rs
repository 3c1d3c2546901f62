//! Scene files as text: TOML with a `[scene]` table and one phenomenon's tables, or
//! several phenomena's (a [`crate::shot`]).
//! Every problem (syntax, unknown keys, bad values, values out of range) is reported
//! with its line and column, all of them at once.

use std::path::{Path, PathBuf};

use toml::de::DeTable;

use crate::registry::{self, Entry};
use crate::scene::Scene;
use crate::source::{SceneErrors, Source, locate};

/// Largest scene file, bytes (strokes and keyframes are text; 16 MiB is far more than
/// any drawn scene).
pub const MAX_SCENE_BYTES: u64 = 16 << 20;

/// Why a scene file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file could not be read.
    #[error("{}: cannot read the scene file: {problem}", .file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// Why.
        problem: String,
    },
    /// The file has problems.
    #[error(transparent)]
    Scene(#[from] SceneErrors),
}

/// Read (a regular file of at most [`MAX_SCENE_BYTES`]), parse and validate a scene file.
pub fn load(path: &Path) -> Result<Scene, LoadError> {
    let read_error = |problem: String| LoadError::Read { file: path.to_path_buf(), problem };
    let bytes = crate::assets::read_file(path, MAX_SCENE_BYTES, false).map_err(read_error)?;
    let text = String::from_utf8(bytes).map_err(|e| read_error(format!("not UTF-8 text ({e})")))?;
    Ok(parse(&text, path)?)
}

/// Parse and validate scene text; `file` names it in messages.
pub fn parse(text: &str, file: impl AsRef<Path>) -> Result<Scene, SceneErrors> {
    let source = Source { file: file.as_ref().to_path_buf(), text: text.to_string() };
    let root = DeTable::parse(text).map_err(|e| {
        SceneErrors(vec![source.at(e.span().map_or(0, |s| s.start), e.message().trim().to_string())])
    })?;
    let present: Vec<Entry> = registry::PHENOMENA
        .iter()
        .copied()
        .filter(|p| !p.composite() && root.get_ref().get(p.name()).is_some())
        .collect();
    let entry = match present.as_slice() {
        [one] => *one,
        [] => {
            let names: Vec<String> = registry::PHENOMENA
                .iter()
                .filter(|p| !p.composite())
                .map(|p| format!("[{}]", p.name()))
                .collect();
            return Err(SceneErrors(vec![source.at(
                0,
                format!(
                    "no phenomenon table: a scene holds one or more of {} (e.g. a [flame] table)",
                    names.join(", ")
                ),
            )]));
        }
        // Several phenomena: a shot.
        _ => match registry::PHENOMENA.iter().copied().find(|p| p.composite()) {
            Some(shot) => shot,
            None => unreachable!("the registry lists the shot"),
        },
    };
    // Every problem at once: what cannot be read, and what the rest (read with those
    // entries left out) breaks of the valid ranges.
    let (mut problems, scene) = match entry.ops().parse_file(text) {
        Ok(file) => (Vec::new(), Some(Scene::from_parts(entry, file, None))),
        Err((errors, rest)) => (errors, rest.map(|file| Scene::from_parts(entry, file, None))),
    };
    if let Some(scene) = &scene {
        let blanked: Vec<usize> = problems.iter().map(|p| p.0).collect();
        for issue in scene.validate() {
            let offset = locate(root.get_ref(), &issue.field);
            // A key left out holds its default: a problem reported there is the one found.
            if !blanked.contains(&offset) {
                problems.push((offset, issue.to_string()));
            }
        }
    }
    match scene {
        Some(scene) if problems.is_empty() => Ok(scene.with_source(source)),
        _ => {
            problems.sort_by_key(|p| p.0);
            Err(SceneErrors(
                problems.into_iter().map(|(offset, message)| source.at(offset, message)).collect(),
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn errors(text: &str) -> Vec<String> {
        match parse(text, "s.toml") {
            Ok(_) => Vec::new(),
            Err(e) => e.0.iter().map(|l| l.to_string()).collect(),
        }
    }

    #[test]
    fn syntax_errors_are_located() {
        let e = errors("[flame]\nmode = \"paper\"\nsubsteps = = 2\n");
        assert_eq!(e.len(), 1);
        assert!(e[0].starts_with("s.toml:3:"), "{e:?}");
    }

    #[test]
    fn every_unknown_key_and_bad_value_is_reported() {
        let e = errors(
            "[scene]\nwidth = 0\nframez = 3\n[flame]\nsubstepz = 2\n[flame.sph]\ngas_constant = -1\nsupport_radius_m = \"big\"\n",
        );
        // The range problem of the rest (width = 0) comes with the unreadable entries.
        assert_eq!(e.len(), 5, "{e:?}");
        assert!(e[0].starts_with("s.toml:2:9: scene.width = 0"), "{e:?}");
        assert!(e[1].starts_with("s.toml:3:1: unknown field `framez`"), "{e:?}");
        assert!(e.iter().any(|m| m.starts_with("s.toml:5:1: unknown field `substepz`")), "{e:?}");
        assert!(e.iter().any(|m| m.starts_with("s.toml:7:1: unknown field `gas_constant`")), "{e:?}");
        assert!(e.iter().any(|m| m.starts_with("s.toml:8:")), "{e:?}");
    }

    #[test]
    fn unknown_keys_are_located() {
        let e = errors("[flame]\n[flame.sph]\nsupport_radius = 0.1\n");
        assert_eq!(e.len(), 1);
        assert!(e[0].starts_with("s.toml:3:1: unknown field `support_radius`"), "{e:?}");
    }
    /// A key scene files once held says it was removed and what to do.
    #[test]
    fn removed_keys_say_so() {
        let text = "[aurora]\n[render.sky.yields]\no1d_per_o_ion = 0.5\n";
        let Err(errors) = parse(text, "s.toml") else { panic!("an old key was accepted") };
        let e: Vec<String> = errors.0.iter().map(ToString::to_string).collect();
        assert!(e[0].starts_with("s.toml:3:1: unknown field `o1d_per_o_ion`"), "{e:?}");
        assert!(e[0].contains("computed from its sources"), "{e:?}");
    }

    #[test]
    fn out_of_range_values_are_located_at_the_value() {
        let text = "[scene]\nwidth = 0\n[flame.sph]\ngas_constant_m2_s2 = -2.0\n[[flame.wind.keys]]\ntime_s = 1\nforce_n_m3 = [0, 0, 0]\n[[flame.wind.keys]]\ntime_s = 0.5\nforce_n_m3 = [1, 0, 0]\n";
        let e = errors(text);
        assert_eq!(e.len(), 3, "{e:?}");
        assert_eq!(e[0], "s.toml:2:9: scene.width = 0: expected an integer in [1, 16384]");
        assert!(e[1].starts_with("s.toml:4:22: flame.sph.gas_constant_m2_s2 = -2"), "{e:?}");
        assert!(e[2].starts_with("s.toml:9:10: flame.wind.keys[1].time_s = 0.5"), "{e:?}");
    }

    #[test]
    fn phenomenon_table_is_required_and_unique() {
        let e = errors("[scene]\nframes = 3\n");
        assert!(e[0].contains("no phenomenon table"), "{e:?}");
        let e = errors("[flmae]\n");
        assert!(e[0].contains("no phenomenon table"), "{e:?}");
        // Two phenomena make a shot.
        assert!(parse("[flame]\n[sparkle]\nfps = 60.0\n", "s.toml").is_ok());
    }

    #[test]
    fn later_problems_are_located_at_their_key() {
        let scene =
            parse("[scene]\nframes = 2\n\n[geometry]\nmesh = \"yard.glb\"\n[snow]\n", "y.toml").unwrap();
        let at = scene.locate("geometry.mesh", "no such file".into()).unwrap();
        assert_eq!(at.to_string(), "y.toml:5:8: no such file");
    }

    #[test]
    fn the_guides_scene_example_is_valid() {
        let guide = include_str!("../../../docs/guide.md");
        let start = guide.find("```toml\n").expect("the guide has a TOML example") + 8;
        let end = start + guide[start..].find("```").expect("closed");
        if let Err(e) = parse(&guide[start..end], "docs/guide.md") {
            panic!("{e}");
        }
    }
}
