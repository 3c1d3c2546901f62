//! Configuration checking shared by every phenomenon: each problem names the field (as a
//! dotted path, e.g. `sph.gas_constant`), the offending value and what is valid.
//!
//! ```
//! use phenomena_core::validate::Issues;
//! let mut issues = Issues::default();
//! issues.range("sph.support_radius_m", -1.0, 1e-4..=10.0);
//! let err = issues.into_result().unwrap_err();
//! assert_eq!(err[0].to_string(), "sph.support_radius_m = -1: expected a value in [0.0001, 10]");
//! ```

use std::fmt;
use std::ops::RangeInclusive;

/// One invalid configuration value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Issue {
    /// Dotted path of the field inside the phenomenon's table, e.g. `emitter.rate`.
    pub field: String,
    /// The offending value as written.
    pub value: String,
    /// What would be valid, e.g. `a value in [0, 1]`.
    pub expected: String,
}

impl Issue {
    /// A problem explained in words rather than as a value outside a range (e.g. two
    /// strokes that cross): displayed as `field: text`.
    pub fn described(field: impl Into<String>, text: impl Into<String>) -> Self {
        Self { field: field.into(), value: String::new(), expected: text.into() }
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

/// Collects every problem of a configuration, not just the first.
#[derive(Clone, Debug, Default)]
pub struct Issues {
    list: Vec<Issue>,
}

impl Issues {
    /// Record a problem.
    pub fn push(&mut self, field: impl Into<String>, value: impl fmt::Display, expected: impl Into<String>) {
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
            self.push(field, value, format!("a value in [{}, {}]", range.start(), range.end()));
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
            self.push(field, value, format!("a value in ({lo}, {hi}]"));
        }
    }

    /// Require an integer in `range`.
    pub fn count(&mut self, field: &str, value: u64, range: RangeInclusive<u64>) {
        if !range.contains(&value) {
            self.push(field, value, format!("an integer in [{}, {}]", range.start(), range.end()));
        }
    }

    /// Require every component finite and of magnitude at most `max_abs`.
    pub fn vector(&mut self, field: &str, v: &[f32], max_abs: f64) {
        if v.iter().any(|c| !c.is_finite() || f64::from(c.abs()) > max_abs) {
            self.push(field, format!("{v:?}"), format!("finite components within ±{max_abs}"));
        }
    }

    /// Add another list's problems, prefixing their field paths with `prefix.`.
    pub fn extend_prefixed(&mut self, prefix: &str, other: Vec<Issue>) {
        for mut issue in other {
            issue.field = format!("{prefix}.{}", issue.field);
            self.list.push(issue);
        }
    }

    /// Whether nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// `Ok(())` when nothing was recorded, else every problem.
    pub fn into_result(self) -> Result<(), Vec<Issue>> {
        if self.list.is_empty() { Ok(()) } else { Err(self.list) }
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
    }
}
