//! Issue 20's image criterion: thesis scene 2 (`scenes/aurora-scene2.toml`) rendered at
//! 1280 × 720 in the physical mode with default settings shows a redder upper border:
//! the top third of the curtain is at least 1.2× redder (R/G) than its middle third.
//!
//! Frame: 140, the scene's second keyframe (the S-shape of the thesis's Fig. 3.5): the
//! sheet has had 140 frames to follow its transition and stands as one folded curtain
//! before the split (the scenario test `scene2_s_shape_and_split` counts one cloud
//! there). The colour by height does not depend on the shape in plan, so any frame with
//! a formed curtain would do; this one is the scene's own reference view.
//!
//! Which pixels are the curtain: in each image column, the rows whose luminance is at
//! least 2 % of the frame's brightest pixel; the column's curtain runs from its highest
//! to its lowest such row and is cut into thirds by row. R and G are summed over the
//! top and the middle thirds of all columns (linear sRGB, as rendered).

mod common;

use phenomena_aurora::{SkyRenderer, SkySettings};
use phenomena_core::image::Frame;

/// (R/G of the top third, R/G of the middle third) of the curtain in `frame`.
fn thirds_redness(frame: &Frame, floor_share: f32) -> (f64, f64) {
    let (w, h) = (frame.width(), frame.height());
    let lum = |x: usize, y: usize| {
        let p = frame.pixel(x, y);
        0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z
    };
    let max = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| lum(x, y)).fold(0.0f32, f32::max);
    let floor = floor_share * max;
    let (mut top, mut middle) = ([0.0f64; 2], [0.0f64; 2]);
    for x in 0..w {
        let lit: Vec<usize> = (0..h).filter(|&y| lum(x, y) >= floor).collect();
        let (Some(&first), Some(&last)) = (lit.first(), lit.last()) else { continue };
        let span = (last - first + 1) as f64;
        for y in first..=last {
            let third = ((y - first) as f64 / span * 3.0) as usize;
            let p = frame.pixel(x, y);
            let acc = match third {
                0 => &mut top,
                1 => &mut middle,
                _ => continue,
            };
            acc[0] += f64::from(p.x);
            acc[1] += f64::from(p.y);
        }
    }
    (top[0] / top[1], middle[0] / middle[1])
}

#[test]
#[allow(clippy::print_stderr, reason = "the measurement, for the record of a run")]
fn scene2_has_a_redder_upper_border() {
    if !common::slow_tests() {
        return; // a slow test (140 frames of 120,000 particles): PHENOMENA_SLOW_TESTS=1 runs it
    }
    let (config, _, seed) = common::load("aurora-scene2.toml");
    let sim = common::run(config, seed, 140);
    let mut sky = SkyRenderer::new(SkySettings::default(), 1280, 720, None).expect("sky");
    let frame = sky.render(&sim).clone();
    let (top, middle) = thirds_redness(&frame, 0.02);
    eprintln!(
        "scene 2, frame 140, 1280x720: R/G top third {top:.3}, middle third {middle:.3}, ratio {:.3}",
        top / middle
    );
    assert!(top >= 1.2 * middle, "top third R/G {top}, middle third {middle}");
}
