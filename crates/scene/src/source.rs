//! Scene text and places in it: a problem at a file's line and column ([`Located`]),
//! the text kept with a parsed scene to locate later problems ([`Source`]), and reading
//! a phenomenon's tables with every problem collected ([`deserialize_all`]).

use std::fmt;
use std::path::PathBuf;

use toml::de::{DeTable, DeValue};

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

    pub(crate) fn at(&self, offset: usize, message: String) -> Located {
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
pub(crate) fn locate(root: &DeTable<'_>, field: &str) -> usize {
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

    #[test]
    fn line_and_column_are_one_based_characters() {
        assert_eq!(line_column("ab\ncdé\nx", 0), (1, 1));
        assert_eq!(line_column("ab\ncdé\nx", 3), (2, 1));
        assert_eq!(line_column("ab\ncdé\nx", 8), (3, 1));
        assert_eq!(line_column("ab\ncdé\nx", 99), (3, 2));
        assert_eq!(line_column("ab\ncdé\nx", 7), (2, 4));
    }
}
