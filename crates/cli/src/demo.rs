//! `phenomena demo`: a short showcase of every system, from the shipped scenes that
//! the registry gives a demo part (embedded in the binary).

use std::path::Path;

use anyhow::Result;
use phenomena_scene::{Assets, registry, shipped};

use crate::export::{self, TableFormat};
use crate::render::{self, RenderJob};

/// Render the showcase into `out`; returns a summary of what was written.
pub(crate) fn run(out: &Path, threads: Option<usize>) -> Result<String> {
    let mut lines = Vec::new();
    for shipped in shipped::SHIPPED.iter() {
        let Some(demo) = &shipped.demo else { continue };
        let scene = shipped.scene()?;
        let mut job = RenderJob {
            width: Some(demo.size.0),
            height: Some(demo.size.1),
            threads,
            ..RenderJob::new(out.join(shipped.name), registry::FORMATS[0])
        };
        job.job.frames = Some(demo.frames.clone());
        // Shipped scenes read no files.
        lines.push(render::run_scene(scene, &Assets::none(), &job)?);
    }
    let strip = out.join("blackbody-1000K-10000K.png");
    lines.push(export::blackbody(1000.0, 10000.0, 10.0, TableFormat::Png, &strip)?);
    lines.push(format!("demo written to {}", out.display()));
    Ok(lines.join("\n"))
}
