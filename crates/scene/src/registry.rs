//! The registry of phenomena and the registry of shipped scenes: the only lists of
//! them. The CLI (`render`, `validate`, `new`, `demo`, `export`), the studio and the
//! tests read these.
//!
//! Adding a phenomenon: write its module (a file struct implementing
//! [`Phenomenon`]) and add one line to [`PHENOMENA`].

use std::marker::PhantomData;
use std::ops::Range;

use serde_json::Value;

use crate::output::Format;
use crate::parse::deserialize_all;
use crate::phenomenon::{ExportKind, Phenomenon, View};
use crate::scene::Scene;

/// Every phenomenon, in the order tools list them.
pub const PHENOMENA: &[&dyn Entry] = &[
    &Registered::<crate::flame::FlameScene>(PhantomData),
    &Registered::<crate::aurora::AuroraScene>(PhantomData),
    &Registered::<crate::snow::SnowScene>(PhantomData),
    &Registered::<crate::sparkle::SparkleScene>(PhantomData),
];

/// A phenomenon as tools see it, without its types.
pub trait Entry: Sync {
    /// Its table name (`flame`).
    fn name(&self) -> &'static str;
    /// One line on what it is.
    fn about(&self) -> &'static str;
    /// Its views; the first is the default.
    fn views(&self) -> &'static [View];
    /// Its data exports.
    fn exports(&self) -> &'static [ExportKind];
    /// The formats `render` writes for it; the first is the default.
    fn formats(&self) -> &'static [Format];
    /// Its commented starter scene.
    fn starter(&self) -> &'static str;
    /// A scene holding every default.
    fn default_scene(&self) -> Scene;
    /// Deserialize a scene file's text as this phenomenon's (not validated); every
    /// problem as (byte offset, message).
    fn parse_file(&self, text: &str) -> Result<Scene, crate::parse::Unread<Scene>>;
    /// A scene from its JSON form (what [`Scene::to_json`] gives; not validated).
    fn scene_from_json(&self, value: Value) -> Result<Scene, String>;
}

/// The phenomenon `name`.
pub fn phenomenon(name: &str) -> Option<&'static dyn Entry> {
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

struct Registered<P>(PhantomData<fn() -> P>);

impl<P: Phenomenon> Entry for Registered<P> {
    fn name(&self) -> &'static str {
        P::NAME
    }

    fn about(&self) -> &'static str {
        P::ABOUT
    }

    fn views(&self) -> &'static [View] {
        P::VIEWS
    }

    fn exports(&self) -> &'static [ExportKind] {
        P::EXPORTS
    }

    fn formats(&self) -> &'static [Format] {
        P::FORMATS
    }

    fn starter(&self) -> &'static str {
        P::STARTER
    }

    fn default_scene(&self) -> Scene {
        Scene::new(P::default())
    }

    fn parse_file(&self, text: &str) -> Result<Scene, crate::parse::Unread<Scene>> {
        deserialize_all::<P>(text).map(Scene::new).map_err(|(errors, rest)| (errors, rest.map(Scene::new)))
    }

    fn scene_from_json(&self, value: Value) -> Result<Scene, String> {
        serde_json::from_value::<P>(value).map(Scene::new).map_err(|e| e.to_string())
    }
}

/// How `phenomena demo` shows a shipped scene.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Demo {
    /// The frames written (earlier ones are simulated).
    pub frames: Range<u32>,
    /// Width and height, pixels.
    pub size: (u32, u32),
}

/// A scene shipped in `scenes/`, embedded so `demo`, the studio and `new` work anywhere.
#[derive(Clone, Debug)]
pub struct Shipped {
    /// File name in `scenes/` without `.toml`.
    pub name: &'static str,
    /// Its phenomenon's table name.
    pub phenomenon: &'static str,
    /// The file's text.
    pub text: &'static str,
    /// Its part of `phenomena demo`, if any.
    pub demo: Option<Demo>,
}

impl Shipped {
    /// The scene, parsed (named `scenes/NAME.toml` in messages).
    pub fn scene(&self) -> Result<Scene, crate::parse::SceneErrors> {
        crate::parse::parse(self.text, format!("scenes/{}.toml", self.name))
    }
}

macro_rules! shipped {
    ($name:literal, $phenomenon:literal) => {
        Shipped {
            name: $name,
            phenomenon: $phenomenon,
            text: include_str!(concat!("../../../scenes/", $name, ".toml")),
            demo: None,
        }
    };
    ($name:literal, $phenomenon:literal, demo $a:literal .. $b:literal at $w:literal x $h:literal) => {
        Shipped {
            name: $name,
            phenomenon: $phenomenon,
            text: include_str!(concat!("../../../scenes/", $name, ".toml")),
            demo: Some(Demo { frames: $a..$b, size: ($w, $h) }),
        }
    };
}

/// Every scene in `scenes/`; the first of each phenomenon is the one the studio's tab
/// opens with. `phenomena demo` renders those with a [`Demo`], in this order.
pub static SHIPPED: [Shipped; 17] = [
    shipped!("flame-paper", "flame", demo 120..121 at 640 x 360),
    shipped!("flame-campfire", "flame", demo 30..150 at 960 x 540),
    shipped!("flame-wind-left", "flame", demo 120..121 at 640 x 360),
    shipped!("flame-wind-right", "flame", demo 120..121 at 640 x 360),
    shipped!("aurora-scene2", "aurora", demo 230..231 at 640 x 360),
    shipped!("aurora-scene1", "aurora"),
    shipped!("aurora-scene3", "aurora"),
    shipped!("aurora-scene4", "aurora"),
    shipped!("aurora-scene5", "aurora"),
    shipped!("snow-table", "snow", demo 59..60 at 640 x 480),
    shipped!("snow-primitives", "snow"),
    shipped!("snow-village", "snow"),
    shipped!("snow-yard", "snow"),
    shipped!("sparkle-diamond-dust", "sparkle", demo 0..30 at 960 x 540),
    shipped!("sparkle-leaf-glitter", "sparkle", demo 60..61 at 960 x 540),
    shipped!("sparkle-sun-pillar", "sparkle"),
    shipped!("sparkle-paper", "sparkle"),
];

/// The shipped scene `name`.
pub fn shipped(name: &str) -> Option<&'static Shipped> {
    SHIPPED.iter().find(|s| s.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shipped_scene_is_registered_valid_and_of_its_phenomenon() {
        for s in &SHIPPED {
            let scene = s.scene().unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(scene.phenomenon().name(), s.phenomenon, "{}", s.name);
        }
        // That every file in scenes/ is listed is the tidy test's (crates/cli/tests/tidy.rs).
    }

    /// The yard's benchmark and tests use `yard_config()`; the shipped scene is the same.
    #[test]
    fn the_shipped_yard_is_the_benchmarks_yard() {
        let scene = shipped("snow-yard").expect("registered").scene().unwrap_or_else(|e| panic!("{e}"));
        let snow = scene.get::<crate::snow::SnowScene>().expect("a snow scene");
        assert_eq!(snow.snow, phenomena_snow::mesh::yard_config());
        assert_eq!(snow.geometry.builtin, Some(phenomena_snow::mesh::Builtin::Yard));
    }

    #[test]
    fn every_phenomenon_has_a_shipped_scene_first_in_its_tab_and_unique_names() {
        for p in PHENOMENA {
            assert!(SHIPPED.iter().any(|s| s.phenomenon == p.name()), "{}", p.name());
            assert!(!p.views().is_empty(), "{}", p.name());
        }
        let mut names: Vec<&str> = PHENOMENA.iter().map(|p| p.name()).collect();
        names.dedup();
        assert_eq!(names.len(), PHENOMENA.len());
        assert_eq!(super::names(), "flame, aurora, snow or sparkle");
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
