//! Work filed by bands of image rows, so that rows can be drawn in parallel and every
//! pixel still sums its contributions in one fixed order, whatever the thread count.
//!
//! Each renderer cuts its image into bands of rows; each item (a splat, a glint, an
//! emission point) touches a run of bands. [`Filed`] is a counting sort of items by
//! band that keeps their order within each band (and copies an item into every band it
//! touches). Work made in parallel chunks is filed per chunk; a band then reads its run
//! from every chunk in chunk order: item order, for any thread count. The flame's
//! splats, the sparkle's glints and the aurora's emission points are all filed here.
//!
//! ```
//! use phenomena_core::bands::Filed;
//! // Items at rows 3, 9 and 4..=9, bands of 4 rows: bands 0 and 2, and 1..=2.
//! let rows = [(3u32, 3u32), (9, 9), (4, 9)];
//! let filed = Filed::file(3, rows.len(), |i| Some((rows[i].0 / 4, rows[i].1 / 4)), |i| rows[i].0);
//! assert_eq!(filed.band(0), [3]);
//! assert_eq!(filed.band(1), [4]);
//! assert_eq!(filed.band(2), [9, 4]); // item order kept
//! ```

/// Items filed by band (compressed rows: one run per band).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Filed<T> {
    items: Vec<T>,
    /// Start of each band's run in `items`; `bands + 1` entries.
    start: Vec<u32>,
}

impl<T: Copy + Default> Filed<T> {
    /// File items `0..count` into `bands` bands: `span(i)` gives the first and last band
    /// item `i` touches (inclusive, each below `bands`), or `None` to leave it out;
    /// `keep(i)` makes what is filed (an index, or the item when it is small). Within
    /// each band items keep their order.
    pub fn file(
        bands: usize,
        count: usize,
        span: impl Fn(usize) -> Option<(u32, u32)>,
        keep: impl Fn(usize) -> T,
    ) -> Self {
        let mut filed = Self::default();
        filed.refile(bands, count, span, keep);
        filed
    }

    /// As [`Filed::file`], into this one's memory (kept between frames).
    pub fn refile(
        &mut self,
        bands: usize,
        count: usize,
        span: impl Fn(usize) -> Option<(u32, u32)>,
        keep: impl Fn(usize) -> T,
    ) {
        let start = &mut self.start;
        start.clear();
        start.resize(bands + 1, 0);
        for i in 0..count {
            if let Some((lo, hi)) = span(i) {
                for b in lo..=hi {
                    start[b as usize + 1] += 1;
                }
            }
        }
        for b in 0..bands {
            start[b + 1] += start[b];
        }
        let mut next = start[..bands].to_vec();
        self.items.clear();
        self.items.resize(start[bands] as usize, T::default());
        for i in 0..count {
            if let Some((lo, hi)) = span(i) {
                let t = keep(i);
                for b in lo..=hi {
                    let at = &mut next[b as usize];
                    self.items[*at as usize] = t;
                    *at += 1;
                }
            }
        }
    }
}

impl<T> Filed<T> {
    /// The items of band `b`, in their order.
    #[inline]
    pub fn band(&self, b: usize) -> &[T] {
        &self.items[self.start[b] as usize..self.start[b + 1] as usize]
    }

    /// Number of bands.
    pub fn bands(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// Entries filed over all bands (an item in two bands counts twice).
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether nothing was filed.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Filing equals, band by band, the items in order that touch the band.
    #[test]
    fn filing_is_a_stable_partition_by_band() {
        let mut rng = crate::rng::Stream::new(5, crate::rng::Purpose::named("test.bands"), 0);
        let bands = 7;
        let items: Vec<(u32, u32, u32)> = (0..500)
            .map(|i| {
                let lo = rng.below(bands);
                let hi = (lo + rng.below(3)).min(bands - 1);
                (i, lo, hi)
            })
            .collect();
        let drop_every_fifth = |k: usize| {
            let (i, lo, hi) = items[k];
            (i % 5 != 0).then_some((lo, hi))
        };
        let filed = Filed::file(bands as usize, items.len(), drop_every_fifth, |k| items[k].0);
        assert_eq!(filed.bands(), bands as usize);
        for b in 0..bands {
            let expect: Vec<u32> = items
                .iter()
                .filter(|&&(i, lo, hi)| i % 5 != 0 && (lo..=hi).contains(&b))
                .map(|&(i, _, _)| i)
                .collect();
            assert_eq!(filed.band(b as usize), expect, "band {b}");
        }
        let empty = Filed::<u32>::file(3, 0, |_| Some((0, 2)), |k| k as u32);
        assert!(empty.is_empty() && empty.band(2).is_empty());
    }
}
