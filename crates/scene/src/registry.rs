//! The registry of phenomena: the only list of them. The CLI (`render`, `validate`,
//! `new`, `demo`, `export`), the studio, the output formats and the contract tests read
//! it ([`crate::shipped`] lists the scenes shipped in `scenes/`).
//!
//! Adding a phenomenon: write its module (a file struct implementing
//! [`crate::Phenomenon`]) and add one line to [`PHENOMENA`].

pub use crate::entry::Entry;
use crate::format::Format;

/// Every phenomenon, in the order tools list them.
pub const PHENOMENA: &[Entry] = &[
    Entry::of::<crate::flame::FlameScene>(),
    Entry::of::<crate::aurora::AuroraScene>(),
    Entry::of::<crate::snow::SnowScene>(),
    Entry::of::<crate::sparkle::SparkleScene>(),
    Entry::of::<crate::shot::ShotScene>(),
];

/// Every output format, in the order tools list them; the first is the default. A
/// format is one module implementing [`crate::format::OutputFormat`] and one line here.
pub const FORMATS: &[Format] = &[
    Format::new(&crate::png::Png),
    Format::new(&crate::exr::Exr),
    Format::new(&crate::vdb::Vdb),
    Format::new(&crate::ply::Ply),
    Format::new(&crate::flipbook::Flipbook),
];

impl Format {
    /// The format named `name`.
    pub fn named(name: &str) -> Option<Format> {
        FORMATS.iter().copied().find(|f| f.name() == name)
    }

    /// The formats phenomenon `entry` can be written in; the first is the default.
    pub fn of(entry: Entry) -> Vec<Format> {
        FORMATS.iter().copied().filter(|f| f.writes(entry)).collect()
    }

    /// `Ok` when phenomenon `entry` can be written in this format, else an error
    /// naming the formats it can.
    pub fn check(self, entry: Entry) -> Result<(), String> {
        if self.writes(entry) {
            return Ok(());
        }
        let names: Vec<&str> = Format::of(entry).iter().map(|f| f.name()).collect();
        Err(format!("{} scenes are not written as {}: use {}", entry.name(), self.name(), names.join(", ")))
    }
}

/// The phenomenon `name`.
pub fn phenomenon(name: &str) -> Option<Entry> {
    PHENOMENA.iter().copied().find(|p| p.name() == name)
}

/// The names of every phenomenon, joined for messages: `flame, aurora, snow or sparkle`.
pub fn names() -> String {
    let names: Vec<&str> = PHENOMENA.iter().map(|p| p.name()).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => names.join(""),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_phenomenon_has_a_shipped_scene_first_in_its_tab_and_unique_names() {
        for p in PHENOMENA {
            assert!(crate::shipped::SHIPPED.iter().any(|s| s.phenomenon == p.name()), "{}", p.name());
            assert!(!p.views().is_empty(), "{}", p.name());
        }
        let mut names: Vec<&str> = PHENOMENA.iter().map(|p| p.name()).collect();
        names.dedup();
        assert_eq!(names.len(), PHENOMENA.len());
        assert_eq!(super::names(), "flame, aurora, snow, sparkle or shot");
    }

    /// Every format has a unique name; png is first (the default) and every
    /// phenomenon can be written as png and exr.
    #[test]
    fn format_names_are_unique_and_images_are_for_everyone() {
        let mut names: Vec<&str> = FORMATS.iter().map(|f| f.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), FORMATS.len());
        assert_eq!(FORMATS[0].name(), "png");
        for p in PHENOMENA {
            let formats = Format::of(*p);
            assert!(formats.iter().any(|f| f.name() == "png") && formats.iter().any(|f| f.name() == "exr"));
        }
    }

    /// `phenomena new` writes these: each parses to exactly the defaults.
    #[test]
    fn every_starter_holds_exactly_the_defaults() {
        for p in PHENOMENA {
            let scene = crate::parse(p.starter(), format!("{}.toml", p.name()))
                .unwrap_or_else(|e| panic!("{} starter: {e}", p.name()));
            assert_eq!(scene, p.default_scene(), "{} starter", p.name());
        }
    }
}
