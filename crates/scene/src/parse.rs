//! Scene files as text: TOML with a `[scene]` table and exactly one phenomenon's tables.
//! Every problem (syntax, unknown keys, bad values, values out of range) is reported
//! with its line and column, all of them at once.

use std::fmt;
use std::path::{Path, PathBuf};

use toml::de::{DeTable, DeValue};

use crate::registry::{self, Entry};
use crate::scene::Scene;

/// A problem at a place in a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Located {
    /// The file, as the caller named it.
    pub file: PathBuf,
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for Located {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: {}", self.file.display(), self.line, self.column, self.message)
    }
}

/// Problems found in a scene file (at least one).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneErrors(pub Vec<Located>);

impl fmt::Display for SceneErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (k, e) in self.0.iter().enumerate() {
            if k > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for SceneErrors {}

/// A scene file's text, kept with a parsed scene to locate later problems (a missing
/// mesh, say) at the key that caused them.
#[derive(Debug)]
pub(crate) struct Source {
    pub(crate) file: PathBuf,
    pub(crate) text: String,
}

impl Source {
    /// A problem with `field` (a dotted path such as `flame.wind.keys[1].time_s`) at its
    /// place in the file, or at the closest enclosing item written in it.
    pub(crate) fn locate(&self, field: &str, message: String) -> Located {
        let offset = DeTable::parse(&self.text).map_or(0, |root| locate(root.get_ref(), field));
        self.at(offset, message)
    }

    fn at(&self, offset: usize, message: String) -> Located {
        let (line, column) = line_column(&self.text, offset);
        Located { file: self.file.clone(), line, column, message }
    }
}

/// 1-based line and column (in characters) of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..text.floor_char_boundary(offset)];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

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
    let present: Vec<&'static dyn Entry> =
        registry::PHENOMENA.iter().copied().filter(|p| root.get_ref().get(p.name()).is_some()).collect();
    let entry = match present.as_slice() {
        [one] => *one,
        [] => {
            let names: Vec<String> = registry::PHENOMENA.iter().map(|p| format!("[{}]", p.name())).collect();
            return Err(SceneErrors(vec![source.at(
                0,
                format!(
                    "no phenomenon table: a scene holds exactly one of {} (e.g. a [flame] table)",
                    names.join(", ")
                ),
            )]));
        }
        several => {
            let second = several[1].name();
            let offset = root.get_ref().get(second).map_or(0, |v| v.span().start);
            let names: Vec<&str> = several.iter().map(|p| p.name()).collect();
            return Err(SceneErrors(vec![source.at(
                offset,
                format!("a scene holds one phenomenon, but this file has [{}]", names.join("], [")),
            )]));
        }
    };
    // Every problem at once: what cannot be read, and what the rest (read with those
    // entries left out) breaks of the valid ranges.
    let (mut problems, scene) = match entry.parse_file(text) {
        Ok(scene) => (Vec::new(), Some(scene)),
        Err((errors, rest)) => (errors, rest),
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

/// Keys that scene files once held, with what to do instead: an old scene's unknown
/// field then says why rather than only listing the fields there are.
const REMOVED_KEYS: &[(&str, &str)] = &[
    (
        "o1d_per_o_ion",
        "removed: the aurora's O(¹D) (the 630.0 nm line) is now computed from its sources, \
         electron impact and the ion chemistry; delete the line",
    ),
    (
        "o1d_per_o2_ion",
        "removed: the aurora's O(¹D) (the 630.0 nm line) is now computed from its sources, \
         electron impact and the ion chemistry; delete the line",
    ),
];

/// `message` with a hint appended when it names an unknown field listed in [`REMOVED_KEYS`].
fn with_removal_hint(message: &str) -> String {
    let hint = REMOVED_KEYS
        .iter()
        .find(|(key, _)| message.starts_with(&format!("unknown field `{key}`")))
        .map(|(_, hint)| hint);
    match hint {
        Some(hint) => format!("{message} ({hint})"),
        None => message.to_string(),
    }
}

/// What [`deserialize_all`] found wrong: (byte offset, message) per problem, and the
/// value read once every offending entry was blanked out (their defaults in their
/// place), if it could be read, so its other problems can be found too.
pub(crate) type Unread<T> = (Vec<(usize, String)>, Option<T>);

/// Deserialize, collecting every unknown key and bad value rather than stopping at the
/// first: after each error the offending `key = value` is blanked out (positions kept)
/// and the text is read again.
pub(crate) fn deserialize_all<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, Unread<T>> {
    const MAX_ERRORS: usize = 50;
    let mut work = text.to_string();
    let mut errors: Vec<(usize, String)> = Vec::new();
    let mut rest = None;
    while errors.len() < MAX_ERRORS {
        match toml::from_str::<T>(&work) {
            Ok(value) if errors.is_empty() => return Ok(value),
            Ok(value) => {
                rest = Some(value);
                break;
            }
            Err(e) => {
                let offset = e.span().map_or(0, |s| s.start);
                let message = with_removal_hint(e.message().trim());
                if errors.last().is_some_and(|last| last.0 == offset && last.1 == message) {
                    break; // blanking did not remove the cause (e.g. a missing field)
                }
                errors.push((offset, message));
                let Some(range) =
                    DeTable::parse(&work).ok().and_then(|root| entry_at(root.get_ref(), offset))
                else {
                    break;
                };
                let blanked: String = work[range.clone()]
                    .chars()
                    .map(|c| if c == '\n' || c == '\r' { c } else { ' ' })
                    .collect();
                work.replace_range(range, &blanked);
                if DeTable::parse(&work).is_err() {
                    break; // blanking inside an inline table broke the syntax: stop here
                }
            }
        }
    }
    errors.sort_by_key(|e| e.0);
    Err((errors, rest))
}

/// The byte range `key = value` of the innermost entry whose key or value contains
/// `offset`.
fn entry_at(table: &DeTable<'_>, offset: usize) -> Option<std::ops::Range<usize>> {
    for (key, value) in table.iter() {
        // Spans of header tables do not always cover their bodies: look inside first.
        let inner = match value.get_ref() {
            DeValue::Table(t) => entry_at(t, offset),
            DeValue::Array(a) => a.iter().find_map(|el| match el.get_ref() {
                DeValue::Table(t) => entry_at(t, offset),
                _ => None,
            }),
            _ => None,
        };
        if inner.is_some() {
            return inner;
        }
        let (k, v) = (key.span(), value.span());
        let whole = k.start.min(v.start)..k.end.max(v.end);
        if whole.contains(&offset) && !matches!(value.get_ref(), DeValue::Table(_)) {
            return Some(whole);
        }
    }
    None
}

/// Byte offset of the value at a dotted field path such as `flame.wind.keys[1].time_s`,
/// or of the closest enclosing item that is written in the file (a default value has no
/// place of its own).
fn locate(root: &DeTable<'_>, field: &str) -> usize {
    let mut offset = 0;
    let mut table: Option<&DeTable<'_>> = Some(root);
    let mut value: Option<&DeValue<'_>> = None;
    for segment in field.split('.') {
        let (key, index) = match segment.split_once('[') {
            Some((k, rest)) => (k, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (segment, None),
        };
        let next = match (table, value) {
            (Some(t), _) => t.get(key),
            (None, Some(v)) => v.as_table().and_then(|t| t.get(key)),
            _ => None,
        };
        let Some(item) = next else { break };
        offset = item.span().start;
        let mut v = item.get_ref();
        if let Some(k) = index {
            match v.as_array().and_then(|a| a.get(k)) {
                Some(el) => {
                    offset = el.span().start;
                    v = el.get_ref();
                }
                None => break,
            }
        }
        table = None;
        value = Some(v);
    }
    offset
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
    fn line_and_column_are_one_based_characters() {
        assert_eq!(line_column("ab\ncdé\nx", 0), (1, 1));
        assert_eq!(line_column("ab\ncdé\nx", 3), (2, 1));
        assert_eq!(line_column("ab\ncdé\nx", 8), (3, 1));
        assert_eq!(line_column("ab\ncdé\nx", 99), (3, 2));
        assert_eq!(line_column("ab\ncdé\nx", 7), (2, 4));
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
        let e = errors("[flame]\n[snow]\n");
        assert_eq!(e, ["s.toml:2:1: a scene holds one phenomenon, but this file has [flame], [snow]"]);
    }

    #[test]
    fn later_problems_are_located_at_their_key() {
        let scene =
            parse("[scene]\nframes = 2\n\n[geometry]\nmesh = \"yard.glb\"\n[snow]\n", "y.toml").unwrap();
        let at = scene.locate("geometry.mesh", "no such file".into()).unwrap();
        assert_eq!(at.to_string(), "y.toml:5:8: no such file");
    }

    #[test]
    fn the_readme_scene_example_is_valid() {
        let readme = include_str!("../../../README.md");
        let start = readme.find("```toml\n").expect("README has a TOML example") + 8;
        let end = start + readme[start..].find("```").expect("closed");
        if let Err(e) = parse(&readme[start..end], "README.md") {
            panic!("{e}");
        }
    }
}
