//! Artist shapes (thesis §2.2.1-2.2.2): strokes resampled to control points, sheets that
//! never cross, split and merge operations, keyframes, and the intermediate target shapes
//! interpolated between them.
//!
//! A *sheet* is one stroke resampled to `n` control points linked in drawing order. A
//! *shape* is the set of control points with their links at one moment. An
//! [`Animation`] holds the keyframes (the source shape at the first, target shapes at the
//! later ones; control points matched in drawing order) and the split and merge
//! operations of each transition, and yields the intermediate target shape at any frame.
//!
//! Control points are numbered per sheet: the stroke's points are `0..n`, and points that
//! a split or merge adds to a sheet continue the numbering (`n`, `n + 1`, ...), in the order
//! the operations are listed.

use glam::Vec2;
use serde::{Deserialize, Serialize};

/// How a stroke's mouse samples become control points (eq 2.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Resample {
    /// As printed: P_i = (1 - p) M_q + p M_{q+1} with q + p = i·m/n. The last control
    /// point falls short of the stroke's end when m > n.
    Paper,
    /// The same interpolation at i·(m - 1)/(n - 1), so the first and last control points
    /// are the stroke's ends (an extension; both rules give the samples themselves when
    /// m = n).
    #[default]
    Endpoints,
}

/// A reference to a control point: sheet number and point number within the sheet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointRef {
    /// Sheet (stroke) number, in drawing order from 0.
    pub sheet: u32,
    /// Control point within the sheet (0..n for the stroke's own points).
    pub point: u32,
}

/// A split (Fig 2.4): the segment starting at `start` opens up during the transition
/// into keyframe `keyframe`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Split {
    /// The keyframe the transition leads to (1 = from the source to the first target).
    pub keyframe: u32,
    /// The control point at which the segment starts (its link leads to the segment end).
    pub start: PointRef,
}

/// A merge (Fig 2.5): two chain ends join during the transition into `keyframe`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Merge {
    /// The keyframe the transition leads to.
    pub keyframe: u32,
    /// One end point (a control point with exactly one link).
    pub a: PointRef,
    /// The other end point.
    pub b: PointRef,
}

/// One keyframe as the artist drew it: strokes in the x-z plane, km.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Frame number of this shape.
    pub frame: u32,
    /// One stroke (list of [x, z] samples, km) per sheet, in drawing order.
    #[serde(deserialize_with = "phenomena_core::serde_vec::point_lists2")]
    pub sheets: Vec<Vec<[f32; 2]>>,
}

/// Why shapes could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShapeError {
    /// Fewer than two keyframes, or none.
    #[error("an aurora needs a source and at least one target keyframe, got {0} keyframe(s)")]
    TooFewKeyframes(usize),
    /// Keyframe frames must strictly increase.
    #[error("keyframe {index} is at frame {frame}, not after the previous keyframe's frame {previous}")]
    KeyframeOrder {
        /// Keyframe number.
        index: usize,
        /// Its frame.
        frame: u32,
        /// The previous keyframe's frame.
        previous: u32,
    },
    /// A keyframe has a different number of sheets than the source.
    #[error(
        "keyframe {keyframe} has {found} sheet(s) but the source has {expected}: sheets are matched in drawing order"
    )]
    SheetCount {
        /// Keyframe number.
        keyframe: usize,
        /// Its sheet count.
        found: usize,
        /// The source's sheet count.
        expected: usize,
    },
    /// A stroke has fewer than two samples.
    #[error("keyframe {keyframe} sheet {sheet} has {samples} sample(s): a stroke needs at least 2")]
    ShortStroke {
        /// Keyframe number.
        keyframe: usize,
        /// Sheet number.
        sheet: usize,
        /// Samples given.
        samples: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("keyframe {keyframe} sheet {sheet} sample {sample} is not a finite point")]
    NonFinite {
        /// Keyframe number.
        keyframe: usize,
        /// Sheet number.
        sheet: usize,
        /// Sample number.
        sample: usize,
    },
    /// Too few control points per sheet.
    #[error("control_points_per_sheet = {0}: expected at least 2")]
    TooFewControlPoints(usize),
    /// Two sheets cross (§2.2.1: aurora sheets never cross).
    #[error(
        "keyframe {keyframe}: sheet {a} crosses sheet {b} (segment {segment_a} of sheet {a} meets segment {segment_b} of sheet {b}); aurora sheets never cross"
    )]
    Crossing {
        /// Keyframe number.
        keyframe: usize,
        /// First sheet.
        a: usize,
        /// Second sheet.
        b: usize,
        /// Segment (start point) in sheet a.
        segment_a: usize,
        /// Segment (start point) in sheet b.
        segment_b: usize,
    },
    /// An operation names a keyframe that has no transition into it.
    #[error("{op} {index} is for keyframe {keyframe}, but transitions lead to keyframes 1..={last}")]
    OpKeyframe {
        /// "split" or "merge".
        op: &'static str,
        /// Operation number in its list.
        index: usize,
        /// The keyframe named.
        keyframe: u32,
        /// The last keyframe.
        last: usize,
    },
    /// A point reference names no existing control point.
    #[error("{op} {index} refers to sheet {sheet} point {point}, which does not exist at that keyframe")]
    NoSuchPoint {
        /// "split" or "merge".
        op: &'static str,
        /// Operation number.
        index: usize,
        /// Sheet named.
        sheet: u32,
        /// Point named.
        point: u32,
    },
    /// A split names a point that starts no segment.
    #[error("split {index}: sheet {sheet} point {point} starts no segment (it is the end of its chain)")]
    NoSegment {
        /// Operation number.
        index: usize,
        /// Sheet.
        sheet: u32,
        /// Point.
        point: u32,
    },
    /// A merge names a point that is not a chain end.
    #[error(
        "merge {index}: sheet {sheet} point {point} has {links} links; only end points (one link) can merge"
    )]
    NotAnEnd {
        /// Operation number.
        index: usize,
        /// Sheet.
        sheet: u32,
        /// Point.
        point: u32,
        /// Its link count.
        links: usize,
    },
    /// A merge names the same point twice.
    #[error("merge {index} joins sheet {sheet} point {point} with itself: name two different chain ends")]
    SelfMerge {
        /// Operation number.
        index: usize,
        /// Sheet.
        sheet: u32,
        /// Point.
        point: u32,
    },
    /// The same operation is listed twice.
    #[error("{op} {index} repeats {op} {first} (same keyframe and points): list each once")]
    Repeated {
        /// "split" or "merge".
        op: &'static str,
        /// The repeat's number.
        index: usize,
        /// The first's number.
        first: usize,
    },
    /// No keyframe has a sheet.
    #[error("the keyframes have no sheets: draw at least one stroke (of two points or more) per keyframe")]
    NoSheets,
}

impl ShapeError {
    /// The scene field (relative to `[aurora]`) the problem is in, for error locations.
    pub fn field(&self) -> String {
        match *self {
            ShapeError::TooFewKeyframes(_) => "keyframes".into(),
            ShapeError::KeyframeOrder { index, .. } => format!("keyframes[{index}].frame"),
            ShapeError::SheetCount { keyframe, .. } => format!("keyframes[{keyframe}].sheets"),
            ShapeError::ShortStroke { keyframe, sheet, .. }
            | ShapeError::NonFinite { keyframe, sheet, .. } => {
                format!("keyframes[{keyframe}].sheets[{sheet}]")
            }
            ShapeError::TooFewControlPoints(_) => "shape.control_points_per_sheet".into(),
            ShapeError::Crossing { keyframe, b, .. } => format!("keyframes[{keyframe}].sheets[{b}]"),
            ShapeError::OpKeyframe { op, index, .. } | ShapeError::NoSuchPoint { op, index, .. } => {
                format!("{op}s[{index}]")
            }
            ShapeError::NoSegment { index, .. } => format!("splits[{index}]"),
            ShapeError::NotAnEnd { index, .. } | ShapeError::SelfMerge { index, .. } => {
                format!("merges[{index}]")
            }
            ShapeError::Repeated { op, index, .. } => format!("{op}s[{index}]"),
            ShapeError::NoSheets => "keyframes[0].sheets".into(),
        }
    }
}

/// Resample a stroke to `n` control points by eq (2.1).
pub fn resample(stroke: &[Vec2], n: usize, rule: Resample) -> Vec<Vec2> {
    let m = stroke.len();
    if m == 0 || n == 0 {
        return Vec::new();
    }
    (0..n)
        .map(|i| {
            let s = match rule {
                Resample::Paper => i as f64 * m as f64 / n as f64,
                Resample::Endpoints if n > 1 => i as f64 * (m - 1) as f64 / (n - 1) as f64,
                Resample::Endpoints => 0.0,
            };
            let q = (s.floor() as usize).min(m - 1);
            let p = (s - q as f64) as f32;
            let a = stroke[q];
            let b = stroke[(q + 1).min(m - 1)];
            a * (1.0 - p) + b * p
        })
        .collect()
}

/// Whether segments ab and cd intersect (touching and collinear overlap count).
pub fn segments_intersect(a: Vec2, b: Vec2, c: Vec2, d: Vec2) -> bool {
    fn orient(p: Vec2, q: Vec2, r: Vec2) -> f32 {
        (q - p).perp_dot(r - p)
    }
    fn on_segment(p: Vec2, q: Vec2, r: Vec2) -> bool {
        r.x >= p.x.min(q.x) && r.x <= p.x.max(q.x) && r.y >= p.y.min(q.y) && r.y <= p.y.max(q.y)
    }
    let (d1, d2, d3, d4) = (orient(c, d, a), orient(c, d, b), orient(a, b, c), orient(a, b, d));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && on_segment(c, d, a))
        || (d2 == 0.0 && on_segment(c, d, b))
        || (d3 == 0.0 && on_segment(a, b, c))
        || (d4 == 0.0 && on_segment(a, b, d))
}

/// Control points and their links at one moment.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Shape {
    /// Control point positions (x, z), km.
    pub points: Vec<Vec2>,
    /// Link from each point to the next one of its chain, if any (one entry per point).
    pub next: Vec<Option<u32>>,
    /// Sheet of each point.
    pub sheet: Vec<u32>,
    /// Number of each point within its sheet.
    pub index_in_sheet: Vec<u32>,
}

impl Shape {
    /// The segments (start, end) in point order.
    pub fn segments(&self) -> impl Iterator<Item = (Vec2, Vec2)> + '_ {
        self.next.iter().enumerate().filter_map(|(i, n)| n.map(|j| (self.points[i], self.points[j as usize])))
    }

    /// Number of segments.
    pub fn segment_count(&self) -> usize {
        self.next.iter().filter(|n| n.is_some()).count()
    }

    /// Axis-aligned bounds of the control points (min, max).
    pub fn bounds(&self) -> (Vec2, Vec2) {
        self.points.iter().fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)))
    }

    /// Distance from `p` to the nearest segment (infinite if there is none).
    pub fn distance(&self, p: Vec2) -> f32 {
        self.segments().map(|(a, b)| point_segment_distance(p, a, b)).fold(f32::INFINITY, f32::min)
    }
}

/// Distance from `p` to the segment ab.
#[inline]
pub fn point_segment_distance(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (a + ab * t).distance(p)
}

/// How a point's position in one keyframe follows from others (for points added by
/// operations, which the artist did not draw).
#[derive(Clone, Copy, Debug)]
enum Rule {
    /// Drawn by the artist: given in every keyframe.
    Drawn,
    /// Before keyframe `from`: the midpoint of a and b; from it on: at `anchor`.
    SplitEnd { from: usize, a: u32, b: u32, anchor: u32 },
    /// Before keyframe `from`: at `anchor`; from it on: the midpoint of a and b.
    MergeEnd { from: usize, anchor: u32, a: u32, b: u32 },
}

/// The source and target shapes with their operations: intermediate target shapes at
/// any frame (§2.2.2).
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    frames: Vec<f32>,
    /// positions[k][p]: control point p at keyframe k.
    positions: Vec<Vec<Vec2>>,
    /// Links in force during the transition into keyframe t (index t - 1).
    topology: Vec<Vec<Option<u32>>>,
    sheet: Vec<u32>,
    index_in_sheet: Vec<u32>,
    /// Per point, per keyframe: the spline's first derivative (x and z), km per frame.
    slopes: Vec<Vec<Vec2>>,
}

impl Animation {
    /// Build the animation: resample every stroke to `n` control points, check that
    /// sheets never cross in any keyframe, apply the operations in order, and fit the
    /// interpolating splines.
    pub fn build(
        keyframes: &[Keyframe],
        splits: &[Split],
        merges: &[Merge],
        n: usize,
        rule: Resample,
    ) -> Result<Self, ShapeError> {
        if n < 2 {
            return Err(ShapeError::TooFewControlPoints(n));
        }
        if keyframes.len() < 2 {
            return Err(ShapeError::TooFewKeyframes(keyframes.len()));
        }
        let sheets = keyframes[0].sheets.len();
        if sheets == 0 && keyframes.iter().all(|k| k.sheets.is_empty()) {
            return Err(ShapeError::NoSheets);
        }
        check_operations(splits, merges)?;
        check_keyframes(keyframes, sheets)?;
        let mut positions = resample_keyframes(keyframes, n, rule);
        for (k, pos) in positions.iter().enumerate() {
            check_crossings(pos, sheets, n, k)?;
        }
        let mut book = PointBook::drawn(sheets, n);
        let last = keyframes.len() - 1;
        let mut topology = Vec::with_capacity(last);
        for t in 1..=last {
            book.apply_transition(t, last, splits, merges)?;
            topology.push(book.next.clone());
        }
        let PointBook { sheet, index_in_sheet, rules, .. } = book;
        // Points added by later transitions do not exist yet in earlier ones: unlinked
        // there, so every shape has one link entry per point.
        for links in &mut topology {
            links.resize(rules.len(), None);
        }
        place_added_points(&mut positions, &rules);
        let frames: Vec<f32> = keyframes.iter().map(|k| k.frame as f32).collect();
        let slopes = (0..rules.len())
            .map(|p| {
                let ys: Vec<Vec2> = positions.iter().map(|pos| pos[p]).collect();
                clamped_spline_slopes(&frames, &ys)
            })
            .collect();
        Ok(Self { frames, positions, topology, sheet, index_in_sheet, slopes })
    }

    /// Frame of each keyframe.
    pub fn keyframe_frames(&self) -> &[f32] {
        &self.frames
    }

    /// Number of control points (drawn and added).
    pub fn point_count(&self) -> usize {
        self.sheet.len()
    }

    /// The intermediate target shape at `frame` (clamped to the keyframes' span): each
    /// control point on its clamped cubic spline through the keyframes, with the links
    /// of the transition under way.
    pub fn shape_at(&self, frame: f32) -> Shape {
        let f = frame.clamp(self.frames[0], self.frames[self.frames.len() - 1]);
        // Interval k: frames[k] <= f <= frames[k + 1].
        let k = self.frames.windows(2).position(|w| f <= w[1]).unwrap_or(self.frames.len() - 2);
        let (f0, f1) = (self.frames[k], self.frames[k + 1]);
        let h = f1 - f0;
        let t = (f - f0) / h;
        // Cubic Hermite basis on the interval with the spline's slopes.
        let (t2, t3) = (t * t, t * t * t);
        let (h00, h10, h01, h11) =
            (2.0 * t3 - 3.0 * t2 + 1.0, t3 - 2.0 * t2 + t, -2.0 * t3 + 3.0 * t2, t3 - t2);
        let points = (0..self.point_count())
            .map(|p| {
                let (y0, y1) = (self.positions[k][p], self.positions[k + 1][p]);
                let (m0, m1) = (self.slopes[p][k], self.slopes[p][k + 1]);
                y0 * h00 + m0 * (h10 * h) + y1 * h01 + m1 * (h11 * h)
            })
            .collect();
        Shape {
            points,
            next: self.topology[k].clone(),
            sheet: self.sheet.clone(),
            index_in_sheet: self.index_in_sheet.clone(),
        }
    }
}

/// Slopes of the clamped cubic spline (zero first derivative at both ends) through
/// `(x[k], y[k])`, per component: the C² spline that starts and ends at rest, so that
/// a single transition eases in and out.
fn clamped_spline_slopes(x: &[f32], y: &[Vec2]) -> Vec<Vec2> {
    let n = x.len();
    let mut m = vec![Vec2::ZERO; n];
    if n < 3 {
        return m; // two keyframes: the Hermite cubic with zero end slopes (smoothstep)
    }
    // Interior slopes m_1..m_{n-2} solve (C² continuity at each interior knot):
    // h_k m_{k-1} + 2(h_{k-1} + h_k) m_k + h_{k-1} m_{k+1}
    //   = 3 [h_k (y_k - y_{k-1}) / h_{k-1} + h_{k-1} (y_{k+1} - y_k) / h_k],
    // with m_0 = m_{n-1} = 0. Thomas algorithm in f64.
    let h: Vec<f64> = x.windows(2).map(|w| f64::from(w[1] - w[0])).collect();
    let size = n - 2;
    let mut a = vec![0.0f64; size];
    let mut b = vec![0.0f64; size];
    let mut c = vec![0.0f64; size];
    let mut d = vec![[0.0f64; 2]; size];
    for r in 0..size {
        let k = r + 1;
        a[r] = h[k];
        b[r] = 2.0 * (h[k - 1] + h[k]);
        c[r] = h[k - 1];
        for axis in 0..2 {
            let yv = |i: usize| f64::from(y[i][axis]);
            d[r][axis] =
                3.0 * (h[k] * (yv(k) - yv(k - 1)) / h[k - 1] + h[k - 1] * (yv(k + 1) - yv(k)) / h[k]);
        }
    }
    for r in 1..size {
        let w = a[r] / b[r - 1];
        b[r] -= w * c[r - 1];
        let prev = d[r - 1];
        for (v, p) in d[r].iter_mut().zip(prev) {
            *v -= w * p;
        }
    }
    let mut sol = vec![[0.0f64; 2]; size];
    for r in (0..size).rev() {
        for axis in 0..2 {
            let next = if r + 1 < size { c[r] * sol[r + 1][axis] } else { 0.0 };
            sol[r][axis] = (d[r][axis] - next) / b[r];
        }
    }
    for r in 0..size {
        m[r + 1] = Vec2::new(sol[r][0] as f32, sol[r][1] as f32);
    }
    m
}

/// The first pair of segments (segment of `a`, segment of `b`) at which two polylines
/// meet (touching counts), if any: the one crossing rule of §2.2.1 ("aurora sheets never
/// cross"), used to refuse crossing keyframes and crossing strokes in the editor.
pub fn first_crossing(a: &[Vec2], b: &[Vec2]) -> Option<(usize, usize)> {
    a.windows(2).enumerate().find_map(|(i, sa)| {
        b.windows(2).position(|sb| segments_intersect(sa[0], sa[1], sb[0], sb[1])).map(|j| (i, j))
    })
}

/// Refuse an operation listed twice (the same keyframe and points) and a merge of a
/// point with itself.
fn check_operations(splits: &[Split], merges: &[Merge]) -> Result<(), ShapeError> {
    for (index, sp) in splits.iter().enumerate() {
        if let Some(first) = splits[..index].iter().position(|o| o == sp) {
            return Err(ShapeError::Repeated { op: "split", index, first });
        }
    }
    for (index, mg) in merges.iter().enumerate() {
        if mg.a == mg.b {
            return Err(ShapeError::SelfMerge { index, sheet: mg.a.sheet, point: mg.a.point });
        }
        let same = |o: &Merge| {
            o.keyframe == mg.keyframe && ((o.a, o.b) == (mg.a, mg.b) || (o.a, o.b) == (mg.b, mg.a))
        };
        if let Some(first) = merges[..index].iter().position(same) {
            return Err(ShapeError::Repeated { op: "merge", index, first });
        }
    }
    Ok(())
}

/// Refuse keyframes whose frames do not increase, whose sheet count differs from the
/// source's `sheets`, or whose strokes have fewer than two samples or a non-finite one.
fn check_keyframes(keyframes: &[Keyframe], sheets: usize) -> Result<(), ShapeError> {
    for (k, kf) in keyframes.iter().enumerate() {
        if k > 0 && kf.frame <= keyframes[k - 1].frame {
            return Err(ShapeError::KeyframeOrder {
                index: k,
                frame: kf.frame,
                previous: keyframes[k - 1].frame,
            });
        }
        if kf.sheets.len() != sheets {
            return Err(ShapeError::SheetCount { keyframe: k, found: kf.sheets.len(), expected: sheets });
        }
        for (s, stroke) in kf.sheets.iter().enumerate() {
            if stroke.len() < 2 {
                return Err(ShapeError::ShortStroke { keyframe: k, sheet: s, samples: stroke.len() });
            }
            if let Some(sample) = stroke.iter().position(|p| !p[0].is_finite() || !p[1].is_finite()) {
                return Err(ShapeError::NonFinite { keyframe: k, sheet: s, sample });
            }
        }
    }
    Ok(())
}

/// The drawn control points of every keyframe: each stroke resampled to `n` points by
/// eq (2.1), `positions[k][sheet * n + i]` (km).
fn resample_keyframes(keyframes: &[Keyframe], n: usize, rule: Resample) -> Vec<Vec<Vec2>> {
    keyframes
        .iter()
        .map(|kf| {
            kf.sheets
                .iter()
                .flat_map(|stroke| {
                    let pts: Vec<Vec2> = stroke.iter().map(|p| Vec2::from(*p)).collect();
                    resample(&pts, n, rule)
                })
                .collect()
        })
        .collect()
}

/// The control points while the split and merge operations (Figs 2.4-2.5) are applied:
/// sheet and number of each point, how each is placed, and the links in force.
struct PointBook {
    sheet: Vec<u32>,
    index_in_sheet: Vec<u32>,
    rules: Vec<Rule>,
    next: Vec<Option<u32>>,
    /// Points of each sheet so far (the number the next added point gets).
    sheet_len: Vec<u32>,
}

impl PointBook {
    /// The drawn control points of `sheets` sheets of `n` points (id = sheet * n + i),
    /// each linked to the next one of its sheet.
    fn drawn(sheets: usize, n: usize) -> Self {
        Self {
            sheet: (0..sheets * n).map(|p| (p / n) as u32).collect(),
            index_in_sheet: (0..sheets * n).map(|p| (p % n) as u32).collect(),
            rules: vec![Rule::Drawn; sheets * n],
            next: (0..sheets * n).map(|p| if p % n + 1 < n { Some(p as u32 + 1) } else { None }).collect(),
            sheet_len: vec![n as u32; sheets],
        }
    }

    /// The id of the point `r` names (`op` number `index` for the error).
    fn find(&self, op: &'static str, index: usize, r: PointRef) -> Result<u32, ShapeError> {
        (0..self.sheet.len())
            .find(|&p| self.sheet[p] == r.sheet && self.index_in_sheet[p] == r.point)
            .map(|p| p as u32)
            .ok_or(ShapeError::NoSuchPoint { op, index, sheet: r.sheet, point: r.point })
    }

    /// Number the next point of `sheet` and record how it is placed (its links are the
    /// caller's).
    fn add_point(&mut self, sheet: u32, rule: Rule) {
        self.sheet.push(sheet);
        self.index_in_sheet.push(self.sheet_len[sheet as usize]);
        self.sheet_len[sheet as usize] += 1;
        self.rules.push(rule);
    }

    /// Apply the operations of the transition into keyframe `t` (splits, then merges,
    /// each in list order), refusing any that names a keyframe outside 1..=`last`.
    fn apply_transition(
        &mut self,
        t: usize,
        last: usize,
        splits: &[Split],
        merges: &[Merge],
    ) -> Result<(), ShapeError> {
        for (index, sp) in splits.iter().enumerate() {
            if sp.keyframe == 0 || sp.keyframe as usize > last {
                return Err(ShapeError::OpKeyframe { op: "split", index, keyframe: sp.keyframe, last });
            }
            if sp.keyframe as usize == t {
                self.split(t, index, sp)?;
            }
        }
        for (index, mg) in merges.iter().enumerate() {
            if mg.keyframe == 0 || mg.keyframe as usize > last {
                return Err(ShapeError::OpKeyframe { op: "merge", index, keyframe: mg.keyframe, last });
            }
            if mg.keyframe as usize == t {
                self.merge(t, index, mg)?;
            }
        }
        Ok(())
    }

    /// A split (Fig 2.4) in the transition into keyframe `t`: the segment a→b opens into
    /// two chain ends, one after a and one before b, that start at the segment's midpoint
    /// and move to a and b.
    fn split(&mut self, t: usize, index: usize, sp: &Split) -> Result<(), ShapeError> {
        let a = self.find("split", index, sp.start)?;
        let Some(b) = self.next[a as usize] else {
            return Err(ShapeError::NoSegment { index, sheet: sp.start.sheet, point: sp.start.point });
        };
        let m1 = self.next.len() as u32;
        self.add_point(sp.start.sheet, Rule::SplitEnd { from: t, a, b, anchor: a });
        self.add_point(sp.start.sheet, Rule::SplitEnd { from: t, a, b, anchor: b });
        self.next[a as usize] = Some(m1);
        self.next.push(None);
        self.next.push(Some(b));
        Ok(())
    }

    /// Links of point `p`: its own and those leading into it.
    fn links(&self, p: u32) -> usize {
        usize::from(self.next[p as usize].is_some()) + self.next.iter().filter(|&&x| x == Some(p)).count()
    }

    /// A merge (Fig 2.5) in the transition into keyframe `t`: each of the two chain ends
    /// grows a new point that starts on it and moves to the midpoint of the two.
    fn merge(&mut self, t: usize, index: usize, mg: &Merge) -> Result<(), ShapeError> {
        let a = self.find("merge", index, mg.a)?;
        let b = self.find("merge", index, mg.b)?;
        for (r, p) in [(mg.a, a), (mg.b, b)] {
            let links = self.links(p);
            if links != 1 {
                return Err(ShapeError::NotAnEnd { index, sheet: r.sheet, point: r.point, links });
            }
        }
        for (r, p) in [(mg.a, a), (mg.b, b)] {
            let id = self.next.len() as u32;
            self.add_point(r.sheet, Rule::MergeEnd { from: t, anchor: p, a, b });
            if self.next[p as usize].is_none() {
                // p ends its chain: extend it forwards.
                self.next[p as usize] = Some(id);
                self.next.push(None);
            } else {
                // p starts its chain: extend it backwards.
                self.next.push(Some(p));
            }
        }
        Ok(())
    }
}

/// Positions of the added points in every keyframe (km), from their rules: the drawn
/// points are kept; anchors are always earlier points, so one pass in id order suffices.
fn place_added_points(positions: &mut [Vec<Vec2>], rules: &[Rule]) {
    for pos in positions.iter_mut() {
        pos.resize(rules.len(), Vec2::ZERO);
    }
    for (k, pos) in positions.iter_mut().enumerate() {
        for p in 0..rules.len() {
            pos[p] = match rules[p] {
                Rule::Drawn => pos[p],
                Rule::SplitEnd { from, a, b, anchor } => {
                    if k < from {
                        (pos[a as usize] + pos[b as usize]) * 0.5
                    } else {
                        pos[anchor as usize]
                    }
                }
                Rule::MergeEnd { from, anchor, a, b } => {
                    if k < from {
                        pos[anchor as usize]
                    } else {
                        (pos[a as usize] + pos[b as usize]) * 0.5
                    }
                }
            };
        }
    }
}

/// Refuse sheets that cross each other in one keyframe (§2.2.1).
fn check_crossings(pos: &[Vec2], sheets: usize, n: usize, keyframe: usize) -> Result<(), ShapeError> {
    for sa in 0..sheets {
        for sb in sa + 1..sheets {
            let (a, b) = (&pos[sa * n..(sa + 1) * n], &pos[sb * n..(sb + 1) * n]);
            if let Some((segment_a, segment_b)) = first_crossing(a, b) {
                return Err(ShapeError::Crossing { keyframe, a: sa, b: sb, segment_a, segment_b });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(x0: f32, z0: f32, x1: f32, z1: f32, m: usize) -> Vec<[f32; 2]> {
        (0..m)
            .map(|i| {
                let t = i as f32 / (m - 1) as f32;
                [x0 + (x1 - x0) * t, z0 + (z1 - z0) * t]
            })
            .collect()
    }

    #[test]
    fn resampling_follows_eq_2_1() {
        let stroke: Vec<Vec2> = (0..10).map(|i| Vec2::new(i as f32, 0.0)).collect();
        // Paper: i·m/n with m = 10, n = 4: 0, 2.5, 5, 7.5.
        let p = resample(&stroke, 4, Resample::Paper);
        assert_eq!(p.iter().map(|v| v.x).collect::<Vec<_>>(), vec![0.0, 2.5, 5.0, 7.5]);
        // Endpoints: i·9/3: 0, 3, 6, 9.
        let e = resample(&stroke, 4, Resample::Endpoints);
        assert_eq!(e.iter().map(|v| v.x).collect::<Vec<_>>(), vec![0.0, 3.0, 6.0, 9.0]);
        // m = n: both give the samples themselves.
        let same = resample(&stroke, 10, Resample::Paper);
        assert_eq!(same, stroke);
    }

    #[test]
    fn crossing_strokes_are_refused() {
        let kf =
            Keyframe { frame: 0, sheets: vec![line(0.0, 0.0, 10.0, 10.0, 5), line(0.0, 10.0, 10.0, 0.0, 5)] };
        let kf2 = Keyframe { frame: 10, ..kf.clone() };
        let e = Animation::build(&[kf, kf2], &[], &[], 8, Resample::Endpoints).unwrap_err();
        assert!(matches!(e, ShapeError::Crossing { keyframe: 0, a: 0, b: 1, .. }), "{e}");
        assert!(segments_intersect(Vec2::ZERO, Vec2::X, Vec2::X, Vec2::new(2.0, 0.0)), "touching counts");
        assert!(!segments_intersect(Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::new(1.0, 1.0)));
        // The first meeting pair, by segment of the first polyline then of the second.
        let zigzag = [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(2.0, 2.0), Vec2::new(3.0, 2.0)];
        let bar = [Vec2::new(1.5, -1.0), Vec2::new(1.5, 3.0)];
        assert_eq!(first_crossing(&zigzag, &bar), Some((1, 0)));
        assert_eq!(first_crossing(&bar, &zigzag), Some((0, 1)));
        assert_eq!(first_crossing(&zigzag[..2], &bar), None);
    }

    #[test]
    fn a_single_transition_eases_in_and_out() {
        let src = Keyframe { frame: 0, sheets: vec![line(0.0, 0.0, 10.0, 0.0, 2)] };
        let dst = Keyframe { frame: 100, sheets: vec![line(0.0, 10.0, 10.0, 10.0, 2)] };
        let anim = Animation::build(&[src, dst], &[], &[], 2, Resample::Endpoints).unwrap();
        let z = |f: f32| anim.shape_at(f).points[0].y;
        assert_eq!(z(0.0), 0.0);
        assert_eq!(z(100.0), 10.0);
        assert!((z(50.0) - 5.0).abs() < 1e-5);
        // smoothstep: 3t² - 2t³ at t = 0.25 is 0.15625.
        assert!((z(25.0) - 1.5625).abs() < 1e-4);
        assert_eq!(z(-10.0), 0.0);
        assert_eq!(z(500.0), 10.0);
    }

    #[test]
    fn splines_pass_through_every_keyframe_smoothly() {
        let kfs: Vec<Keyframe> = [(0, 0.0), (40, 8.0), (100, 2.0), (140, 5.0)]
            .iter()
            .map(|&(f, z)| Keyframe { frame: f, sheets: vec![line(0.0, z, 10.0, z, 2)] })
            .collect();
        let anim = Animation::build(&kfs, &[], &[], 2, Resample::Endpoints).unwrap();
        for (f, z) in [(0.0, 0.0), (40.0, 8.0), (100.0, 2.0), (140.0, 5.0)] {
            assert!((anim.shape_at(f).points[0].y - z).abs() < 1e-4);
        }
        // C¹ at the interior keyframes: left and right difference quotients agree.
        for f in [40.0, 100.0] {
            let e = 1e-2;
            let left = (anim.shape_at(f).points[0].y - anim.shape_at(f - e).points[0].y) / e;
            let right = (anim.shape_at(f + e).points[0].y - anim.shape_at(f).points[0].y) / e;
            assert!((left - right).abs() < 1e-2, "slope jump at {f}: {left} vs {right}");
        }
    }

    #[test]
    fn a_split_opens_the_selected_segment_gradually() {
        let src = Keyframe { frame: 0, sheets: vec![line(0.0, 0.0, 30.0, 0.0, 4)] };
        let dst = Keyframe { frame: 100, sheets: vec![line(0.0, 0.0, 30.0, 0.0, 4)] };
        let split = Split { keyframe: 1, start: PointRef { sheet: 0, point: 1 } };
        let anim = Animation::build(&[src, dst], &[split], &[], 4, Resample::Endpoints).unwrap();
        assert_eq!(anim.point_count(), 6);
        let at0 = anim.shape_at(0.0);
        // Fig 2.4(a): links 0-1, 1-m1, m2-2, 2-3; m1 = m2 = midpoint of 1 and 2.
        assert_eq!(at0.next, vec![Some(1), Some(4), Some(3), None, None, Some(2)]);
        assert_eq!(at0.points[4], Vec2::new(15.0, 0.0));
        assert_eq!(at0.points[5], Vec2::new(15.0, 0.0));
        assert_eq!(at0.index_in_sheet[4..], [4, 5]);
        // Fig 2.4(b): in the target, m1 sits on point 1 and m2 on point 2: the gap is the
        // whole segment; halfway it is half open.
        let end = anim.shape_at(100.0);
        assert_eq!((end.points[4], end.points[5]), (end.points[1], end.points[2]));
        let mid = anim.shape_at(50.0);
        let gap = mid.points[5].x - mid.points[4].x;
        assert!((gap - 5.0).abs() < 1e-4, "{gap}");
    }

    /// Points added by a later transition exist, unlinked, in earlier shapes: every
    /// shape has one link per point (exports and editors index links by point).
    #[test]
    fn every_shape_has_one_link_per_point() {
        let kf = |frame| Keyframe { frame, sheets: vec![line(0.0, 0.0, 30.0, 0.0, 4)] };
        let split = Split { keyframe: 2, start: PointRef { sheet: 0, point: 1 } };
        let anim =
            Animation::build(&[kf(0), kf(50), kf(100)], &[split], &[], 4, Resample::Endpoints).unwrap();
        for frame in [0.0, 25.0, 50.0, 75.0, 100.0] {
            let s = anim.shape_at(frame);
            assert_eq!(s.next.len(), s.points.len(), "frame {frame}");
            assert!(s.next.iter().flatten().all(|&j| (j as usize) < s.points.len()));
        }
        assert_eq!(anim.shape_at(0.0).next[4..], [None, None], "not yet split: unlinked");
    }

    /// Operations that would quietly do something else are refused, each at
    /// its place in the scene.
    #[test]
    fn repeated_self_and_empty_operations_are_refused() {
        let kf = |frame| Keyframe { frame, sheets: vec![line(0.0, 0.0, 30.0, 0.0, 4)] };
        let build = |splits: &[Split], merges: &[Merge]| {
            Animation::build(&[kf(0), kf(50)], splits, merges, 4, Resample::Endpoints).unwrap_err()
        };
        let split = Split { keyframe: 1, start: PointRef { sheet: 0, point: 1 } };
        let e = build(&[split, split], &[]);
        assert_eq!(e, ShapeError::Repeated { op: "split", index: 1, first: 0 });
        assert_eq!(e.field(), "splits[1]");
        let end = PointRef { sheet: 0, point: 3 };
        let e = build(&[], &[Merge { keyframe: 1, a: end, b: end }]);
        assert_eq!(e.field(), "merges[0]");
        assert!(e.to_string().contains("with itself"), "{e}");
        let empty = |frame| Keyframe { frame, sheets: vec![] };
        let e = Animation::build(&[empty(0), empty(9)], &[], &[], 4, Resample::Endpoints).unwrap_err();
        assert_eq!(
            (e, ShapeError::NoSheets.field()),
            (ShapeError::NoSheets, "keyframes[0].sheets".to_string())
        );
    }

    #[test]
    fn a_merge_joins_two_ends_at_their_midpoint() {
        let src =
            Keyframe { frame: 0, sheets: vec![line(0.0, 0.0, 10.0, 0.0, 3), line(20.0, 0.0, 30.0, 0.0, 3)] };
        let dst = src.clone();
        let dst = Keyframe { frame: 60, ..dst };
        let merge =
            Merge { keyframe: 1, a: PointRef { sheet: 0, point: 2 }, b: PointRef { sheet: 1, point: 0 } };
        let anim = Animation::build(&[src, dst], &[], &[merge], 3, Resample::Endpoints).unwrap();
        let s0 = anim.shape_at(0.0);
        // New points 6 (on sheet 0's end) and 7 (on sheet 1's start), zero-length at first.
        assert_eq!(s0.next[2], Some(6));
        assert_eq!(s0.next[7], Some(3));
        assert_eq!((s0.points[6], s0.points[7]), (s0.points[2], s0.points[3]));
        let s1 = anim.shape_at(60.0);
        assert_eq!(s1.points[6], Vec2::new(15.0, 0.0));
        assert_eq!(s1.points[7], Vec2::new(15.0, 0.0));
        // Only end points merge.
        let bad =
            Merge { keyframe: 1, a: PointRef { sheet: 0, point: 1 }, b: PointRef { sheet: 1, point: 0 } };
        let src =
            Keyframe { frame: 0, sheets: vec![line(0.0, 0.0, 10.0, 0.0, 3), line(20.0, 0.0, 30.0, 0.0, 3)] };
        let e = Animation::build(
            &[src.clone(), Keyframe { frame: 9, ..src }],
            &[],
            &[bad],
            3,
            Resample::Endpoints,
        )
        .unwrap_err();
        assert_eq!(e, ShapeError::NotAnEnd { index: 0, sheet: 0, point: 1, links: 2 });
    }

    #[test]
    fn bad_descriptions_are_named() {
        let one = Keyframe { frame: 5, sheets: vec![line(0.0, 0.0, 1.0, 0.0, 3)] };
        assert_eq!(
            Animation::build(std::slice::from_ref(&one), &[], &[], 4, Resample::Paper),
            Err(ShapeError::TooFewKeyframes(1))
        );
        let earlier = Keyframe { frame: 5, ..one.clone() };
        assert!(matches!(
            Animation::build(&[one.clone(), earlier], &[], &[], 4, Resample::Paper),
            Err(ShapeError::KeyframeOrder { index: 1, frame: 5, previous: 5 })
        ));
        let later = Keyframe { frame: 9, ..one.clone() };
        let split = Split { keyframe: 1, start: PointRef { sheet: 0, point: 3 } };
        assert_eq!(
            Animation::build(&[one.clone(), later.clone()], &[split], &[], 4, Resample::Paper),
            Err(ShapeError::NoSegment { index: 0, sheet: 0, point: 3 })
        );
        let split = Split { keyframe: 2, start: PointRef { sheet: 0, point: 0 } };
        assert!(matches!(
            Animation::build(&[one.clone(), later.clone()], &[split], &[], 4, Resample::Paper),
            Err(ShapeError::OpKeyframe { op: "split", .. })
        ));
        let split = Split { keyframe: 1, start: PointRef { sheet: 3, point: 0 } };
        assert!(matches!(
            Animation::build(&[one.clone(), later.clone()], &[split], &[], 4, Resample::Paper),
            Err(ShapeError::NoSuchPoint { op: "split", sheet: 3, .. })
        ));
        let nan = Keyframe { frame: 9, sheets: vec![vec![[0.0, 0.0], [f32::NAN, 1.0]]] };
        assert!(matches!(
            Animation::build(&[one.clone(), nan], &[], &[], 4, Resample::Paper),
            Err(ShapeError::NonFinite { keyframe: 1, sheet: 0, sample: 1 })
        ));
        assert_eq!(
            Animation::build(&[one.clone(), later], &[], &[], 1, Resample::Paper),
            Err(ShapeError::TooFewControlPoints(1))
        );
    }
}
