//! The artist's editor of aurora shapes (thesis §3.1, Figs 3.1-3.3): strokes drawn on a
//! source canvas and on target keyframes, splits, merges and keyframe edits, applied to
//! an [`AuroraConfig`]. Refusals (a stroke that crosses a sheet, a split that opens no
//! segment, ...) leave the configuration as it was. Front ends (the studio) only
//! transport these operations and show [`EditorView`].
//!
//! ```
//! use phenomena_aurora::AuroraConfig;
//! use phenomena_aurora::editor::{Drawn, EditOp, edit};
//! let mut config = AuroraConfig::default();
//! let mut drawn = Drawn::of(&config);
//! edit(&mut config, &mut drawn, EditOp::Clear).unwrap();
//! let line = |z: f32| (0..10).map(|i| [50.0 + 25.0 * i as f32, z]).collect::<Vec<_>>();
//! edit(&mut config, &mut drawn, EditOp::Stroke { keyframe: 0, points: line(100.0) }).unwrap();
//! // A second stroke across the first is refused: aurora sheets never cross.
//! let across = vec![[100.0, 50.0], [100.0, 250.0]];
//! assert!(edit(&mut config, &mut drawn, EditOp::Stroke { keyframe: 0, points: across }).is_err());
//! assert_eq!(config.keyframes[0].sheets.len(), 1);
//! ```

use glam::Vec2;
use serde::{Deserialize, Serialize};

use crate::config::AuroraConfig;
use crate::shape::{Keyframe, Merge, PointRef, Split, first_crossing, resample};

/// One editing operation (what a front end sends, tagged by `op`).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case", deny_unknown_fields)]
pub enum EditOp {
    /// A mouse stroke on keyframe `keyframe`'s canvas, samples in km of the plane. On
    /// the source (keyframe 0) it adds a sheet to every keyframe (a placeholder copy on
    /// the targets); on a target it replaces that keyframe's first placeholder.
    Stroke {
        /// The canvas.
        keyframe: usize,
        /// Mouse samples (x, z), km.
        points: Vec<[f32; 2]>,
    },
    /// Open the segment that starts at (sheet, point) during the transition into
    /// `keyframe`.
    Split {
        /// The transition's target keyframe.
        keyframe: u32,
        /// Sheet of the segment's first point.
        sheet: u32,
        /// The segment's first point.
        point: u32,
    },
    /// Join two chain ends during the transition into `keyframe`.
    Merge {
        /// The transition's target keyframe.
        keyframe: u32,
        /// One end.
        a: PointRef,
        /// The other end.
        b: PointRef,
    },
    /// Add a target keyframe at `frame` (a copy of the last one to draw over).
    AddKeyframe {
        /// Its frame, after the last keyframe's.
        frame: u32,
    },
    /// Move keyframe `keyframe` to `frame`.
    MoveKeyframe {
        /// Which keyframe.
        keyframe: usize,
        /// Its new frame.
        frame: u32,
    },
    /// Delete target keyframe `keyframe` (and its operations).
    DeleteKeyframe {
        /// Which keyframe (not the source).
        keyframe: usize,
    },
    /// Start over: no sheets, a source and one target keyframe.
    Clear,
}

/// Why an operation was refused, in words for the artist.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Refused(pub String);

/// Which sheets of each keyframe the artist drew; the others are placeholders copied
/// from the source, so the configuration stays valid while targets are being drawn.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Drawn(Vec<Vec<bool>>);

impl Drawn {
    /// Every sheet of `config` counted as drawn (a scene read from a file).
    pub fn of(config: &AuroraConfig) -> Self {
        Self(config.keyframes.iter().map(|k| vec![true; k.sheets.len()]).collect())
    }

    /// Whether sheet `sheet` of keyframe `keyframe` was drawn.
    pub fn is_drawn(&self, keyframe: usize, sheet: usize) -> bool {
        self.0.get(keyframe).and_then(|k| k.get(sheet)).copied().unwrap_or(true)
    }

    /// Match the record to `config`'s keyframes and sheets: entries for keyframes or
    /// sheets the record does not know (the configuration was changed by other means)
    /// count as drawn, entries for ones that are gone are dropped.
    pub fn fit(&mut self, config: &AuroraConfig) {
        self.0.resize(config.keyframes.len(), Vec::new());
        for (d, kf) in self.0.iter_mut().zip(&config.keyframes) {
            d.resize(kf.sheets.len(), true);
        }
    }
}

/// Apply one operation. `Ok` may carry a hint for the artist; a refusal leaves
/// `config` and `drawn` as they were.
pub fn edit(config: &mut AuroraConfig, drawn: &mut Drawn, op: EditOp) -> Result<Option<String>, Refused> {
    drawn.fit(config);
    let (config_before, drawn_before) = (config.clone(), drawn.clone());
    let result = apply(config, drawn, op).map_err(Refused);
    if result.is_err() {
        (*config, *drawn) = (config_before, drawn_before);
    }
    result
}

fn apply(config: &mut AuroraConfig, drawn: &mut Drawn, op: EditOp) -> Result<Option<String>, String> {
    match op {
        EditOp::Stroke { keyframe, points } => stroke(config, drawn, keyframe, &points),
        EditOp::Split { keyframe, sheet, point } => {
            config.splits.push(Split { keyframe, start: PointRef { sheet, point } });
            check_animation(config).map(|()| None)
        }
        EditOp::Merge { keyframe, a, b } => {
            if a == b {
                return Err("pick two different end points to merge".into());
            }
            config.merges.push(Merge { keyframe, a, b });
            check_animation(config).map(|()| None)
        }
        EditOp::AddKeyframe { frame } if u64::from(frame) > crate::config::MAX_KEYFRAME => Err(late(frame)),
        EditOp::MoveKeyframe { frame, .. } if u64::from(frame) > crate::config::MAX_KEYFRAME => {
            Err(late(frame))
        }
        EditOp::AddKeyframe { frame } => {
            let prev = config.keyframes.last().map_or(0, |k| k.frame);
            if frame <= prev && !config.keyframes.is_empty() {
                return Err(format!(
                    "a new keyframe goes after the last one (frame {prev}); got frame {frame}"
                ));
            }
            let sheets = config.keyframes.last().map(|k| k.sheets.clone()).unwrap_or_default();
            drawn.0.push(vec![false; sheets.len()]);
            config.keyframes.push(Keyframe { frame, sheets });
            Ok(Some(format!(
                "keyframe {} added at frame {frame}: draw its sheets",
                config.keyframes.len() - 1
            )))
        }
        EditOp::MoveKeyframe { keyframe, frame } => {
            if keyframe >= config.keyframes.len() {
                return Err(format!("there is no keyframe {keyframe}"));
            }
            config.keyframes[keyframe].frame = frame;
            if !config.keyframes.windows(2).all(|w| w[0].frame < w[1].frame) {
                return Err(format!(
                    "keyframe {keyframe} cannot move to frame {frame}: keyframes stay in time order without ties"
                ));
            }
            Ok(None)
        }
        EditOp::DeleteKeyframe { keyframe } => delete_keyframe(config, drawn, keyframe),
        EditOp::Clear => {
            let end = config.keyframes.get(1).map_or(120, |k| k.frame);
            config.keyframes =
                vec![Keyframe { frame: 0, sheets: Vec::new() }, Keyframe { frame: end, sheets: Vec::new() }];
            config.splits.clear();
            config.merges.clear();
            drawn.0 = vec![Vec::new(), Vec::new()];
            Ok(None)
        }
    }
}

/// A stroke on keyframe `k`: resampled as the simulation resamples it, refused if it
/// crosses another sheet of that keyframe.
fn stroke(
    config: &mut AuroraConfig,
    drawn: &mut Drawn,
    k: usize,
    points: &[[f32; 2]],
) -> Result<Option<String>, String> {
    let n = config.shape.control_points_per_sheet as usize;
    let size = config.plane.size_km;
    let Some(last) = config.keyframes.len().checked_sub(1).filter(|&last| k <= last) else {
        return Err(format!("there is no keyframe {k} (keyframes 0..{})", config.keyframes.len()));
    };
    if points.len() < 2 {
        return Err("a stroke needs at least two mouse samples: drag to draw".into());
    }
    if let Some(p) =
        points.iter().find(|p| !((0.0..=size.x).contains(&p[0]) && (0.0..=size.y).contains(&p[1])))
    {
        return Err(format!(
            "stroke point ({}, {}) lies outside the plane [0, {}] x [0, {}] km",
            p[0], p[1], size.x, size.y
        ));
    }
    let raw: Vec<Vec2> = points.iter().map(|p| Vec2::from(*p)).collect();
    let stroke = resample(&raw, n, config.shape.resample);
    let target = if k == 0 {
        None
    } else {
        match drawn.0[k].iter().position(|d| !d) {
            Some(s) => Some(s),
            None => {
                return Err(format!(
                    "every sheet of keyframe {k} is drawn: draw on the source canvas to add a sheet"
                ));
            }
        }
    };
    let crossed = control_points(config, k)
        .iter()
        .enumerate()
        .filter(|(s, _)| Some(*s) != target)
        .find_map(|(s, sheet)| first_crossing(&stroke, sheet).map(|_| s));
    if let Some(s) = crossed {
        return Err(format!(
            "refused: the stroke crosses sheet {s} of keyframe {k} (aurora sheets never cross, thesis §2.2.1)"
        ));
    }
    let sheet: Vec<[f32; 2]> = stroke.iter().map(|p| p.to_array()).collect();
    match target {
        None => {
            for (kf, d) in config.keyframes.iter_mut().zip(drawn.0.iter_mut()) {
                kf.sheets.push(sheet.clone());
                d.push(false);
            }
            let added = config.keyframes[0].sheets.len() - 1;
            drawn.0[0][added] = true;
            Ok((last > 0).then(|| {
                "sheet added: now draw where it goes on the target canvas (the highlighted placeholder)"
                    .to_string()
            }))
        }
        Some(s) => {
            config.keyframes[k].sheets[s] = sheet;
            drawn.0[k][s] = true;
            Ok(None)
        }
    }
}

fn delete_keyframe(
    config: &mut AuroraConfig,
    drawn: &mut Drawn,
    keyframe: usize,
) -> Result<Option<String>, String> {
    if keyframe == 0 {
        return Err("the source keyframe cannot be deleted (use Clear to start over)".into());
    }
    if keyframe >= config.keyframes.len() {
        return Err(format!("there is no keyframe {keyframe}"));
    }
    if config.keyframes.len() <= 2 {
        return Err("an aurora needs a source and at least one target keyframe".into());
    }
    config.keyframes.remove(keyframe);
    drawn.0.remove(keyframe);
    let k = keyframe as u32;
    config.splits.retain(|s| s.keyframe != k);
    config.merges.retain(|m| m.keyframe != k);
    for s in &mut config.splits {
        if s.keyframe > k {
            s.keyframe -= 1;
        }
    }
    for m in &mut config.merges {
        if m.keyframe > k {
            m.keyframe -= 1;
        }
    }
    check_animation(config).map(|()| None)
}

/// The refusal of a keyframe past the last frame shapes are kept at.
fn late(frame: u32) -> String {
    format!("frame {frame} is past the last a keyframe may have ({})", crate::config::MAX_KEYFRAME)
}

fn check_animation(config: &AuroraConfig) -> Result<(), String> {
    config.animation().map(|_| ()).map_err(|e| format!("refused: {e}"))
}

/// The control points of every sheet of keyframe `k`, resampled as the simulation does.
fn control_points(config: &AuroraConfig, k: usize) -> Vec<Vec<Vec2>> {
    let n = config.shape.control_points_per_sheet as usize;
    config.keyframes[k]
        .sheets
        .iter()
        .map(|s| {
            let pts: Vec<Vec2> = s.iter().map(|p| Vec2::from(*p)).collect();
            resample(&pts, n, config.shape.resample)
        })
        .collect()
}

/// What an editor draws: per keyframe, the control points and links as the simulation
/// sees them at that keyframe (splits open, merges joined), which sheets the artist
/// drew, and the sheet the next stroke on that canvas fills.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EditorView {
    /// The plane's size (x, z), km.
    pub plane_km: [f32; 2],
    /// Control points per sheet.
    pub control_points: u32,
    /// Whether the shapes build (sheets, operations and keyframes agree).
    pub built: bool,
    /// Why they do not, if so.
    pub problem: Option<String>,
    /// Per keyframe.
    pub keyframes: Vec<KeyframeView>,
}

/// One keyframe's canvas.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct KeyframeView {
    /// Its frame.
    pub frame: u32,
    /// Per sheet, whether the artist drew it.
    pub drawn: Vec<bool>,
    /// The sheet the next stroke fills (`None`: every sheet is drawn).
    pub next_sheet: Option<usize>,
    /// The points and their links.
    pub shape: ShapeView,
}

/// Control points with their links.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ShapeView {
    /// Positions (x, z), km.
    pub points: Vec<[f32; 2]>,
    /// Link from each point to the next of its chain.
    pub next: Vec<Option<u32>>,
    /// Sheet of each point.
    pub sheet: Vec<u32>,
    /// Number of each point within its sheet.
    pub index: Vec<u32>,
}

/// The editor's view of `config`.
pub fn view(config: &AuroraConfig, drawn: &Drawn) -> EditorView {
    let built = config.animation();
    let keyframes = config
        .keyframes
        .iter()
        .enumerate()
        .map(|(k, kf)| {
            let d: Vec<bool> = (0..kf.sheets.len()).map(|s| drawn.is_drawn(k, s)).collect();
            let next_sheet = if k == 0 { Some(kf.sheets.len()) } else { d.iter().position(|x| !x) };
            let shape = match &built {
                Ok(anim) if !kf.sheets.is_empty() => {
                    let s = anim.shape_at(kf.frame as f32);
                    ShapeView {
                        points: s.points.iter().map(|p| p.to_array()).collect(),
                        next: s.next,
                        sheet: s.sheet,
                        index: s.index_in_sheet,
                    }
                }
                _ => {
                    // The strokes as drawn, each a chain.
                    let mut v = ShapeView::default();
                    for (s, stroke) in kf.sheets.iter().enumerate() {
                        for (i, p) in stroke.iter().enumerate() {
                            let id = v.points.len() as u32;
                            v.points.push(*p);
                            v.next.push((i + 1 < stroke.len()).then_some(id + 1));
                            v.sheet.push(s as u32);
                            v.index.push(i as u32);
                        }
                    }
                    v
                }
            };
            KeyframeView { frame: kf.frame, drawn: d, next_sheet, shape }
        })
        .collect();
    EditorView {
        plane_km: config.plane.size_km.to_array(),
        control_points: config.shape.control_points_per_sheet,
        built: built.is_ok(),
        problem: built.err().map(|e| e.to_string()),
        keyframes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(x0: f32, z0: f32, x1: f32, z1: f32) -> Vec<[f32; 2]> {
        (0..20).map(|i| i as f32 / 19.0).map(|t| [x0 + (x1 - x0) * t, z0 + (z1 - z0) * t]).collect()
    }

    fn stroke(keyframe: usize, points: Vec<[f32; 2]>) -> EditOp {
        EditOp::Stroke { keyframe, points }
    }

    fn started() -> (AuroraConfig, Drawn) {
        let mut c = AuroraConfig::default();
        let mut d = Drawn::of(&c);
        edit(&mut c, &mut d, EditOp::Clear).unwrap();
        (c, d)
    }

    #[test]
    fn the_editor_draws_sources_then_targets_and_refuses_crossings() {
        let (mut c, mut d) = started();
        edit(&mut c, &mut d, stroke(0, line(50.0, 100.0, 300.0, 100.0))).unwrap();
        edit(&mut c, &mut d, stroke(0, line(50.0, 200.0, 300.0, 200.0))).unwrap();
        let n = c.shape.control_points_per_sheet as usize;
        assert_eq!(c.keyframes[0].sheets.len(), 2);
        assert_eq!(c.keyframes[0].sheets[0].len(), n, "strokes are stored resampled");
        assert_eq!(d.0[1], vec![false, false], "targets start as placeholders");
        let e = edit(&mut c, &mut d, stroke(0, line(100.0, 50.0, 100.0, 250.0))).unwrap_err();
        assert!(e.0.contains("crosses sheet 0"), "{e}");
        // The target's next stroke fills sheet 0; one that crosses sheet 1 is refused.
        let e = edit(&mut c, &mut d, stroke(1, line(50.0, 120.0, 300.0, 260.0))).unwrap_err();
        assert!(e.0.contains("crosses sheet 1"), "{e}");
        edit(&mut c, &mut d, stroke(1, line(50.0, 130.0, 300.0, 150.0))).unwrap();
        assert_eq!(d.0[1], vec![true, false]);
        let v = view(&c, &d);
        assert!(v.built, "{v:?}");
        assert_eq!(v.keyframes[1].next_sheet, Some(1));
        assert!(c.validate().is_ok());
    }

    #[test]
    fn split_and_merge_change_the_links_and_bad_ones_are_refused() {
        let (mut c, mut d) = started();
        edit(&mut c, &mut d, stroke(0, line(50.0, 100.0, 300.0, 100.0))).unwrap();
        let links = |c: &AuroraConfig| {
            view(c, &Drawn::of(c)).keyframes[1].shape.next.iter().filter(|x| x.is_some()).count()
        };
        let n = c.shape.control_points_per_sheet as usize;
        assert_eq!(links(&c), n - 1);
        edit(&mut c, &mut d, EditOp::Split { keyframe: 1, sheet: 0, point: 5 }).unwrap();
        // A split adds two points: chains a -> m1 and m2 -> b, one link more in all.
        assert_eq!(links(&c), n);
        let e =
            edit(&mut c, &mut d, EditOp::Split { keyframe: 1, sheet: 0, point: (n - 1) as u32 }).unwrap_err();
        assert!(e.0.contains("starts no segment"), "{e}");
        edit(&mut c, &mut d, EditOp::AddKeyframe { frame: 240 }).unwrap();
        // Merge the two ends of the split (the added points n and n + 1) in the next
        // transition.
        let a = PointRef { sheet: 0, point: n as u32 };
        let b = PointRef { sheet: 0, point: n as u32 + 1 };
        edit(&mut c, &mut d, EditOp::Merge { keyframe: 2, a, b }).unwrap();
        let e = edit(&mut c, &mut d, EditOp::Merge { keyframe: 2, a: PointRef { sheet: 0, point: 3 }, b })
            .unwrap_err();
        assert!(e.0.contains("refused"), "{e}");
        assert!(c.validate().is_ok());
        let e = edit(&mut c, &mut d, EditOp::MoveKeyframe { keyframe: 2, frame: 10 }).unwrap_err();
        assert!(e.0.contains("time order"), "{e}");
        edit(&mut c, &mut d, EditOp::DeleteKeyframe { keyframe: 2 }).unwrap();
        assert!(c.merges.is_empty() && c.keyframes.len() == 2);
    }

    #[test]
    fn a_refusal_leaves_the_shapes_as_they_were() {
        let (mut c, mut d) = started();
        edit(&mut c, &mut d, stroke(0, line(50.0, 100.0, 300.0, 100.0))).unwrap();
        let (c0, d0) = (c.clone(), d.clone());
        for op in [
            stroke(0, line(100.0, 50.0, 100.0, 250.0)),
            stroke(0, vec![[1.0, 1.0]]),
            stroke(0, line(-10.0, 100.0, 50.0, 50.0)),
            stroke(7, line(50.0, 200.0, 300.0, 200.0)),
            EditOp::Split { keyframe: 9, sheet: 0, point: 1 },
            EditOp::DeleteKeyframe { keyframe: 0 },
            EditOp::MoveKeyframe { keyframe: 5, frame: 3 },
            EditOp::AddKeyframe { frame: u32::MAX },
            EditOp::MoveKeyframe { keyframe: 1, frame: u32::MAX },
        ] {
            assert!(edit(&mut c, &mut d, op.clone()).is_err(), "{op:?}");
            assert_eq!((&c, &d), (&c0, &d0), "{op:?} changed the shapes");
        }
    }

    /// A configuration changed behind the editor's back (more keyframes or sheets than
    /// its record) is edited without a panic: the record is fitted first.
    #[test]
    fn keyframes_added_outside_the_editor_can_be_drawn_on() {
        let (mut c, mut d) = started();
        edit(&mut c, &mut d, stroke(0, line(50.0, 100.0, 300.0, 100.0))).unwrap();
        let mut extra = c.keyframes[1].clone();
        extra.frame += 100;
        c.keyframes.push(extra);
        let e = edit(&mut c, &mut d, stroke(2, line(50.0, 150.0, 300.0, 150.0))).unwrap_err();
        assert!(e.0.contains("every sheet of keyframe 2 is drawn"), "{e}");
        edit(&mut c, &mut d, stroke(0, line(50.0, 200.0, 300.0, 200.0))).unwrap();
        assert_eq!(c.keyframes[2].sheets.len(), 2);
        edit(&mut c, &mut d, stroke(2, line(50.0, 220.0, 300.0, 220.0))).unwrap();
        c.keyframes.truncate(2);
        edit(&mut c, &mut d, EditOp::AddKeyframe { frame: 500 }).unwrap();
        assert_eq!(view(&c, &d).keyframes.len(), 3);
    }
}
