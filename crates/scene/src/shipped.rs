//! The scenes shipped in `scenes/`, embedded so `demo`, the studio and `new` work
//! anywhere: the only list of them (the tidy test checks every file in `scenes/` is
//! here).

use std::ops::Range;

use crate::scene::Scene;

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
    /// What it looks like, for people choosing a preset ("Campfire at dusk").
    pub title: &'static str,
    /// The file's text.
    pub text: &'static str,
    /// Its part of `phenomena demo`, if any.
    pub demo: Option<Demo>,
}

impl Shipped {
    /// The scene, parsed (named `scenes/NAME.toml` in messages).
    pub fn scene(&self) -> Result<Scene, crate::source::SceneErrors> {
        crate::parse::parse(self.text, format!("scenes/{}.toml", self.name))
    }
}

macro_rules! shipped {
    ($name:literal, $phenomenon:literal, $title:literal) => {
        Shipped {
            name: $name,
            phenomenon: $phenomenon,
            title: $title,
            text: include_str!(concat!("../../../scenes/", $name, ".toml")),
            demo: None,
        }
    };
    ($name:literal, $phenomenon:literal, $title:literal, demo $a:literal .. $b:literal at $w:literal x $h:literal) => {
        Shipped {
            name: $name,
            phenomenon: $phenomenon,
            title: $title,
            text: include_str!(concat!("../../../scenes/", $name, ".toml")),
            demo: Some(Demo { frames: $a..$b, size: ($w, $h) }),
        }
    };
}

/// Every scene in `scenes/`; the first of each phenomenon is the one the studio's tab
/// opens with. `phenomena demo` renders those with a [`Demo`], in this order.
pub static SHIPPED: [Shipped; 20] = [
    shipped!("flame-campfire", "flame", "Campfire at dusk", demo 30..150 at 960 x 540),
    shipped!("flame-paper", "flame", "Paper flame (Inagaki et al., Fig 8)", demo 120..121 at 640 x 360),
    shipped!("flame-wind-left", "flame", "Flame in a wind from the right (Fig 9)", demo 120..121 at 640 x 360),
    shipped!("flame-wind-right", "flame", "Flame in a wind from the left (Fig 10)", demo 120..121 at 640 x 360),
    shipped!("aurora-scene2", "aurora", "Green curtain with a red top, splitting in two", demo 230..231 at 640 x 360),
    shipped!("aurora-scene1", "aurora", "Curtain peeling back on itself"),
    shipped!("aurora-scene3", "aurora", "Two curtains merging into one long arc"),
    shipped!("aurora-scene4", "aurora", "Folding curtain, split in three, two layers"),
    shipped!("aurora-scene5", "aurora", "Four folding curtains across the sky"),
    shipped!("aurora-flicker", "aurora", "Flickering arc at breakup (60 fps)"),
    shipped!("aurora-pulsating", "aurora", "Pulsating patches in diffuse aurora (40 s)"),
    shipped!("snow-village", "snow", "Snowy village"),
    shipped!("snow-table", "snow", "Snow on and under a garden table", demo 59..60 at 640 x 480),
    shipped!("snow-primitives", "snow", "Snow on simple shapes (paper Fig 8)"),
    shipped!("snow-yard", "snow", "Yard with snow sliding off a steep roof"),
    shipped!("sparkle-diamond-dust", "sparkle", "Diamond dust in low sun", demo 0..30 at 960 x 540),
    shipped!("sparkle-leaf-glitter", "sparkle", "Sunlit leaves glittering", demo 60..61 at 960 x 540),
    shipped!("sparkle-sun-pillar", "sparkle", "Sun pillar over ice plates"),
    shipped!("sparkle-paper", "sparkle", "Paper diamond dust (Table 1)"),
    shipped!("winter-night", "shot", "Winter night: village, aurora, dust and campfire", demo 200..201 at 960 x 540),
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
    }

    /// The yard's benchmark and tests use `yard_config()`; the shipped scene is the same.
    #[test]
    fn the_shipped_yard_is_the_benchmarks_yard() {
        let scene = shipped("snow-yard").expect("registered").scene().unwrap_or_else(|e| panic!("{e}"));
        let snow = scene.get::<crate::snow::SnowScene>().expect("a snow scene");
        assert_eq!(snow.snow, phenomena_snow::mesh::yard_config());
        assert_eq!(snow.geometry.builtin, Some(phenomena_snow::mesh::Builtin::Yard));
    }
}
