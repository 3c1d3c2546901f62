//! `phenomena demo`: a short showcase of every system built so far, from the scenes
//! shipped in `scenes/` (embedded in the binary).

use std::path::{Path, PathBuf};

use anyhow::Result;

use crate::export::{self, TableFormat};
use crate::output::ImageFormat;
use crate::render::{self, RenderJob};
use crate::scene::{self, builtin};

/// One demo item: a built-in scene, the frames to write and a size.
struct Item {
    name: &'static str,
    text: &'static str,
    frames: std::ops::Range<u32>,
    size: (u32, u32),
}

const ITEMS: [Item; 8] = [
    Item { name: "flame-campfire", text: builtin::FLAME_CAMPFIRE, frames: 30..150, size: (960, 540) },
    Item { name: "flame-paper", text: builtin::FLAME_PAPER, frames: 120..121, size: (640, 360) },
    Item { name: "flame-wind-left", text: builtin::FLAME_WIND_LEFT, frames: 120..121, size: (640, 360) },
    Item { name: "flame-wind-right", text: builtin::FLAME_WIND_RIGHT, frames: 120..121, size: (640, 360) },
    Item { name: "aurora-scene2", text: builtin::AURORA_SCENE2, frames: 230..231, size: (640, 360) },
    Item { name: "snow-table", text: builtin::SNOW_TABLE, frames: 59..60, size: (640, 480) },
    Item {
        name: "sparkle-diamond-dust",
        text: builtin::SPARKLE_DIAMOND_DUST,
        frames: 0..30,
        size: (960, 540),
    },
    Item {
        name: "sparkle-leaf-glitter",
        text: builtin::SPARKLE_LEAF_GLITTER,
        frames: 60..61,
        size: (960, 540),
    },
];

/// Render the showcase into `out`; returns a summary of what was written.
pub(crate) fn run(out: &Path, threads: Option<usize>) -> Result<String> {
    let mut lines = Vec::new();
    for item in &ITEMS {
        let path = PathBuf::from(format!("scenes/{}.toml (built in)", item.name));
        let scene = scene::parse(item.text, &path)?;
        let job = RenderJob {
            scene_path: path,
            out_dir: out.join(item.name),
            frames: Some(item.frames.clone()),
            width: Some(item.size.0),
            height: Some(item.size.1),
            seed: None,
            threads,
            format: ImageFormat::Png,
            resume: false,
            stats: None,
            view: None,
            quiet: false,
        };
        lines.push(render::run_scene(scene, &job)?);
    }
    let strip = out.join("blackbody-1000K-10000K.png");
    lines.push(export::blackbody(1000.0, 10000.0, 10.0, TableFormat::Png, &strip)?);
    lines.push(format!("demo written to {}", out.display()));
    Ok(lines.join("\n"))
}
