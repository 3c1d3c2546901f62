//! Helpers shared by the aurora scenario tests: load a shipped scene, run it, measure
//! the particle cloud.

#![allow(dead_code)]

use glam::Vec2;
use phenomena_aurora::field::Grid;
use phenomena_aurora::shape::Shape;
use phenomena_aurora::{AuroraConfig, AuroraSim};
use serde::Deserialize;

#[derive(Deserialize)]
struct SceneFile {
    scene: SceneTable,
    aurora: AuroraConfig,
}

#[derive(Deserialize)]
struct SceneTable {
    frames: u32,
    seed: u64,
}

/// The `[aurora]` table, frame count and seed of `scenes/NAME`.
pub(crate) fn load(name: &str) -> (AuroraConfig, u32, u64) {
    let path = format!("{}/../../scenes/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).expect("scene file");
    let file: SceneFile = toml::from_str(&text).expect("valid scene");
    (file.aurora, file.scene.frames, file.scene.seed)
}

/// Run a simulation for `frames` frames.
pub(crate) fn run(config: AuroraConfig, seed: u64, frames: u32) -> AuroraSim {
    let mut sim = AuroraSim::new(config, seed).expect("valid aurora");
    for _ in 0..frames {
        sim.step().expect("step");
    }
    sim
}

/// Fraction of particles within `reach` of the shape's segments.
pub(crate) fn fraction_near(sim: &AuroraSim, shape: &Shape, reach: f32) -> f64 {
    let p = &sim.particles().position_km;
    p.iter().filter(|&&x| shape.distance(x) < reach).count() as f64 / p.len() as f64
}

/// Points every `step` km along every segment of `shape` that have no particle within
/// `reach` (gaps in the cloud along the shape).
pub(crate) fn gaps_along(sim: &AuroraSim, shape: &Shape, step: f32, reach: f32) -> Vec<Vec2> {
    let p = &sim.particles().position_km;
    let mut grid = phenomena_core::grid::NeighborGrid::default();
    grid.build(p, reach).expect("finite");
    let mut gaps = Vec::new();
    for (a, b) in shape.segments() {
        let n = ((b - a).length() / step).ceil().max(1.0) as usize;
        for k in 0..=n {
            let q = a.lerp(b, k as f32 / n as f32);
            if grid.neighbors_within(p, q, reach).is_empty() {
                gaps.push(q);
            }
        }
    }
    gaps
}

/// Connected components (8-neighbour) of the cells holding at least `min_count`
/// particles, ignoring components smaller than `min_cells` cells.
pub(crate) fn components(sim: &AuroraSim, min_count: u32, min_cells: usize) -> usize {
    let grid: &Grid = sim.grid();
    let counts = phenomena_aurora::field::count_per_cell(grid, &sim.particles().position_km);
    let mut label = vec![usize::MAX; grid.len()];
    let mut found = 0;
    for start in 0..grid.len() {
        if counts[start] < min_count || label[start] != usize::MAX {
            continue;
        }
        let mut stack = vec![start];
        label[start] = start;
        let mut size = 0;
        while let Some(c) = stack.pop() {
            size += 1;
            let (i, j) = ((c % grid.nx) as i64, (c / grid.nx) as i64);
            for dj in -1..=1 {
                for di in -1..=1 {
                    let (ni, nj) = (i + di, j + dj);
                    if ni >= 0 && nj >= 0 && (ni as usize) < grid.nx && (nj as usize) < grid.nz {
                        let k = grid.index(ni as usize, nj as usize);
                        if counts[k] >= min_count && label[k] == usize::MAX {
                            label[k] = start;
                            stack.push(k);
                        }
                    }
                }
            }
        }
        if size >= min_cells {
            found += 1;
        }
    }
    found
}

/// Colour of a sky frame's curtain by height. Which pixels are the
/// curtain: in each image column, the rows whose luminance is at least `floor_share` of
/// the frame's brightest pixel; the column's curtain runs from its highest to its lowest
/// such row and is cut into thirds by row. R, G, B (linear sRGB, as rendered) are summed
/// per third over all columns.
pub(crate) struct CurtainLook {
    /// Summed R, G, B of the top, middle and bottom thirds.
    pub(crate) thirds: [[f64; 3]; 3],
    /// Pixels in the curtains of all columns.
    pub(crate) pixels: usize,
    /// Curtain pixels that are magenta (B and R both above G).
    pub(crate) magenta: usize,
    /// Magenta curtain pixels above the lowest tenth of their column's curtain.
    pub(crate) magenta_above_lowest_tenth: usize,
}

impl CurtainLook {
    /// R/G of third `k` (0 top, 1 middle, 2 bottom).
    pub(crate) fn redness(&self, k: usize) -> f64 {
        self.thirds[k][0] / self.thirds[k][1]
    }
}

/// Measure `frame`'s curtain (see [`CurtainLook`]).
pub(crate) fn curtain_look(frame: &phenomena_core::image::Frame, floor_share: f32) -> CurtainLook {
    let (w, h) = (frame.width(), frame.height());
    let lum = |x: usize, y: usize| {
        let p = frame.pixel(x, y);
        0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z
    };
    let max = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| lum(x, y)).fold(0.0f32, f32::max);
    let floor = floor_share * max;
    let mut look =
        CurtainLook { thirds: [[0.0; 3]; 3], pixels: 0, magenta: 0, magenta_above_lowest_tenth: 0 };
    for x in 0..w {
        let lit: Vec<usize> = (0..h).filter(|&y| lum(x, y) >= floor).collect();
        let (Some(&first), Some(&last)) = (lit.first(), lit.last()) else { continue };
        let span = (last - first + 1) as f64;
        for y in first..=last {
            let f = (y - first) as f64 / span;
            let p = frame.pixel(x, y);
            let acc = &mut look.thirds[((f * 3.0) as usize).min(2)];
            acc[0] += f64::from(p.x);
            acc[1] += f64::from(p.y);
            acc[2] += f64::from(p.z);
            look.pixels += 1;
            if p.x > p.y && p.z > p.y {
                look.magenta += 1;
                if f < 0.9 {
                    look.magenta_above_lowest_tenth += 1;
                }
            }
        }
    }
    look
}

/// `sim`'s sky frame with `settings` at `width` × `height` (linear sRGB).
pub(crate) fn sky_frame(
    sim: &AuroraSim,
    settings: phenomena_aurora::SkySettings,
    width: usize,
    height: usize,
) -> phenomena_core::image::Frame {
    let mut sky = phenomena_aurora::SkyRenderer::new(settings, width, height, None).expect("sky settings");
    sky.render(sim).clone()
}
