//! Configuration checking shared by every phenomenon: each problem names the field (as a
//! dotted path, e.g. `sph.gas_constant`), the offending value and what is valid.
//!
//! What is valid is typed ([`Expected`]: a range, a count, a choice, ...), so a front end
//! can build a control from it without reading the message.
//!
//! ```
//! use phenomena_core::validate::{Expected, Issues};
//! let mut issues = Issues::default();
//! issues.range("sph.support_radius_m", -1.0, 1e-4..=10.0);
//! let err = issues.into_result().unwrap_err();
//! assert_eq!(err[0].to_string(), "sph.support_radius_m = -1: expected a value in [0.0001, 10]");
//! assert_eq!(err[0].expected, Expected::Range { min: 1e-4, max: 10.0, min_open: false });
//! ```

use std::fmt;
use std::ops::RangeInclusive;

/// What a valid value looks like.
#[derive(Clone, Debug, PartialEq)]
pub enum Expected {
    /// A finite number in `[min, max]`, or `(min, max]` when `min_open`.
    Range {
        /// Lower bound.
        min: f64,
        /// Upper bound (always included).
        max: f64,
        /// Whether `min` itself is excluded.
        min_open: bool,
    },
    /// A whole number in `[min, max]`.
    Count {
        /// Smallest valid value.
        min: u64,
        /// Largest valid value.
        max: u64,
    },
    /// A vector whose components are finite and within ±`max_abs`.
    Vector {
        /// Largest magnitude of a component.
        max_abs: f64,
    },
    /// One of these words.
    Choice(Vec<String>),
    /// Anything else, in words (e.g. "every component above domain.min_m").
    Text(String),
}

impl fmt::Display for Expected {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Expected::Range { min, max, min_open: false } => write!(f, "a value in [{min}, {max}]"),
            Expected::Range { min, max, min_open: true } => write!(f, "a value in ({min}, {max}]"),
            Expected::Count { min, max } => write!(f, "an integer in [{min}, {max}]"),
            Expected::Vector { max_abs } => write!(f, "finite components within ±{max_abs}"),
            Expected::Choice(words) => {
                for (k, w) in words.iter().enumerate() {
                    let sep = match k {
                        0 => "",
                        k if k + 1 == words.len() => " or ",
                        _ => ", ",
                    };
                    write!(f, "{sep}\"{w}\"")?;
                }
                Ok(())
            }
            Expected::Text(text) => f.write_str(text),
        }
    }
}

impl From<&str> for Expected {
    fn from(text: &str) -> Self {
        Expected::Text(text.to_string())
    }
}

impl From<String> for Expected {
    fn from(text: String) -> Self {
        Expected::Text(text)
    }
}

/// One invalid configuration value.
#[derive(Clone, Debug, PartialEq)]
pub struct Issue {
    /// Dotted path of the field inside the phenomenon's table, e.g. `emitter.rate`.
    pub field: String,
    /// The offending value as written (empty for an [`Issue::described`] problem).
    pub value: String,
    /// What would be valid.
    pub expected: Expected,
}

impl Issue {
    /// A problem explained in words rather than as a value outside a range (e.g. two
    /// strokes that cross): displayed as `field: text`.
    pub fn described(field: impl Into<String>, text: impl Into<String>) -> Self {
        Self { field: field.into(), value: String::new(), expected: Expected::Text(text.into()) }
    }
}

impl fmt::Display for Issue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.value.is_empty() {
            write!(f, "{}: {}", self.field, self.expected)
        } else {
            write!(f, "{} = {}: expected {}", self.field, self.value, self.expected)
        }
    }
}

impl std::error::Error for Issue {}

/// A configuration that cannot be used, with every problem: the one invalid-config
/// error of every phenomenon's constructors.
#[derive(Clone, Debug, PartialEq)]
pub struct InvalidConfig {
    /// Every problem found.
    pub issues: Vec<Issue>,
}

impl fmt::Display for InvalidConfig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("invalid configuration: ")?;
        for (k, issue) in self.issues.iter().enumerate() {
            if k > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{issue}")?;
        }
        Ok(())
    }
}

impl std::error::Error for InvalidConfig {}

impl From<Vec<Issue>> for InvalidConfig {
    fn from(issues: Vec<Issue>) -> Self {
        Self { issues }
    }
}

impl InvalidConfig {
    /// The same problems with their field paths prefixed by `prefix.` (e.g. the table
    /// a settings struct sits in).
    pub fn prefixed(mut self, prefix: &str) -> Self {
        for issue in &mut self.issues {
            issue.field = format!("{prefix}.{}", issue.field);
        }
        self
    }
}

/// Collects every problem of a configuration, not just the first.
#[derive(Clone, Debug, Default)]
pub struct Issues {
    list: Vec<Issue>,
}

impl Issues {
    /// Record a problem.
    pub fn push(
        &mut self,
        field: impl Into<String>,
        value: impl fmt::Display,
        expected: impl Into<Expected>,
    ) {
        self.list.push(Issue { field: field.into(), value: value.to_string(), expected: expected.into() });
    }

    /// Require `lo <= value <= hi` (and finite). The value is compared and reported as
    /// written (an `f32` prints as the shortest decimal that reads back to it), so
    /// `0.0001` written for an `f32` meets a bound of `0.0001`, although the nearest
    /// `f32` is 9.99999975e-5.
    pub fn range<T: Into<f64> + fmt::Display + Copy>(
        &mut self,
        field: &str,
        value: T,
        range: RangeInclusive<f64>,
    ) {
        let v = as_written(value);
        if !(v.is_finite() && range.contains(&v)) {
            self.push(
                field,
                value,
                Expected::Range { min: *range.start(), max: *range.end(), min_open: false },
            );
        }
    }

    /// Require `lo < value <= hi` (and finite).
    pub fn range_open_low<T: Into<f64> + fmt::Display + Copy>(
        &mut self,
        field: &str,
        value: T,
        lo: f64,
        hi: f64,
    ) {
        let v = as_written(value);
        if !(v.is_finite() && v > lo && v <= hi) {
            self.push(field, value, Expected::Range { min: lo, max: hi, min_open: true });
        }
    }

    /// Require an integer in `range`.
    pub fn count(&mut self, field: &str, value: u64, range: RangeInclusive<u64>) {
        if !range.contains(&value) {
            self.push(field, value, Expected::Count { min: *range.start(), max: *range.end() });
        }
    }

    /// Require every component finite and of magnitude at most `max_abs`.
    pub fn vector(&mut self, field: &str, v: &[f32], max_abs: f64) {
        if v.iter().any(|c| !c.is_finite() || f64::from(c.abs()) > max_abs) {
            self.push(field, format!("{v:?}"), Expected::Vector { max_abs });
        }
    }

    /// Add another list's problems, prefixing their field paths with `prefix.`.
    pub fn extend_prefixed(&mut self, prefix: &str, other: Vec<Issue>) {
        for mut issue in other {
            issue.field = format!("{prefix}.{}", issue.field);
            self.list.push(issue);
        }
    }

    /// How many problems were recorded.
    pub fn len(&self) -> usize {
        self.list.len()
    }

    /// Whether nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// `Ok(())` when nothing was recorded, else every problem.
    pub fn into_result(self) -> Result<(), Vec<Issue>> {
        if self.list.is_empty() { Ok(()) } else { Err(self.list) }
    }

    /// `Ok(())` when nothing was recorded, else the problems as one error.
    pub fn into_config_result(self) -> Result<(), InvalidConfig> {
        self.into_result().map_err(InvalidConfig::from)
    }
}

/// The value as its shortest round-trip decimal reads in `f64` (see [`Issues::range`]).
fn as_written<T: Into<f64> + fmt::Display + Copy>(value: T) -> f64 {
    value.to_string().parse().unwrap_or_else(|_| value.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_values_meet_the_decimal_bounds_they_are_written_as() {
        let mut i = Issues::default();
        i.range("a", 0.0001f32, 0.0001..=100.0);
        i.range("b", 0.1f32, 0.0..=0.1);
        i.range_open_low("c", 0.3f32, 0.0, 0.3);
        assert!(i.is_empty(), "{:?}", i.list);
        i.range("d", 0.000_099_99f32, 0.0001..=100.0);
        assert_eq!(i.list.len(), 1);
    }

    #[test]
    fn collects_every_problem() {
        let mut i = Issues::default();
        i.range("a", f64::NAN, 0.0..=1.0);
        i.range("f", -0.1f32, 0.0..=1.0);
        i.range("b", 0.5, 0.0..=1.0);
        i.range_open_low("c", 0.0, 0.0, 1.0);
        i.count("d", 0, 1..=10);
        i.vector("e", &[0.0, f32::INFINITY], 10.0);
        let errs = i.into_result().unwrap_err();
        let fields: Vec<&str> = errs.iter().map(|e| e.field.as_str()).collect();
        assert_eq!(fields, ["a", "f", "c", "d", "e"]);
        assert_eq!(errs[1].value, "-0.1");
        assert_eq!(errs[2].to_string(), "c = 0: expected a value in (0, 1]");
        assert_eq!(errs[3].to_string(), "d = 0: expected an integer in [1, 10]");
        assert_eq!(errs[3].expected, Expected::Count { min: 1, max: 10 });
        assert_eq!(errs[4].to_string(), "e = [0.0, inf]: expected finite components within ±10");
    }

    #[test]
    fn choices_read_as_a_list() {
        let words = |w: &[&str]| Expected::Choice(w.iter().map(|s| s.to_string()).collect()).to_string();
        assert_eq!(words(&["poly6"]), "\"poly6\"");
        assert_eq!(words(&["poly6", "spiky"]), "\"poly6\" or \"spiky\"");
        assert_eq!(words(&["a", "b", "c"]), "\"a\", \"b\" or \"c\"");
        let e = InvalidConfig::from(vec![Issue::described("x", "bad")]).prefixed("render");
        assert_eq!(e.to_string(), "invalid configuration: render.x: bad");
    }
}
