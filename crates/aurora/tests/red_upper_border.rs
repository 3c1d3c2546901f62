//! Image criterion: thesis scene 2 (`scenes/aurora-scene2.toml`) rendered at
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
//! top and the middle thirds of all columns (linear sRGB, as rendered): `common::curtain_look`.

mod common;

use phenomena_aurora::SkySettings;

#[test]
#[ignore = "slow tier (140 frames of 120,000 particles): cargo test -- --include-ignored"]
#[allow(clippy::print_stderr, reason = "the measurement, for the record of a run")]
fn scene2_has_a_redder_upper_border() {
    let (config, _, seed) = common::load("aurora-scene2.toml");
    let sim = common::run(config, seed, 140);
    let frame = common::sky_frame(&sim, SkySettings::thesis(), 1280, 720);
    let look = common::curtain_look(&frame, 0.02);
    let (top, middle) = (look.redness(0), look.redness(1));
    eprintln!(
        "scene 2, frame 140, 1280x720: R/G top third {top:.3}, middle third {middle:.3}, ratio {:.3}",
        top / middle
    );
    assert!(top >= 1.2 * middle, "top third R/G {top}, middle third {middle}");
}
