//! The fixed reference workload every bench reports beside its own numbers:
//! this machine's speed changes by up to 1.7x between days, so a result reads as a ratio
//! to these two, measured in the same run. Neither depends on any code of ours, and
//! neither may change: a changed reference breaks every ratio in docs/performance.md.
//!
//! - `reference/copy_64mib`: copying 64 MiB of f32 (four times a large L3; memory bound).
//! - `reference/chain_2e22`: 2^22 steps of a dependent integer and floating-point chain
//!   (one core, compute bound, no memory traffic).
//!
//! Included by each crate's bench with `#[path = "../../core/benches/shared/reference.rs"]`.

use criterion::Criterion;
use std::hint::black_box;

/// 64 MiB of f32.
const COPY_LEN: usize = 16 << 20;
/// Steps of the compute chain.
const CHAIN_STEPS: u32 = 1 << 22;

/// A dependent chain: a SplitMix64 step feeding a floating-point multiply-add, so that
/// neither the integer nor the floating-point unit can run ahead.
fn chain(seed: u64) -> f64 {
    let (mut z, mut acc) = (seed, 0.0f64);
    for _ in 0..CHAIN_STEPS {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut x = z;
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        x ^= x >> 31;
        acc = acc.mul_add(0.999_999, (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64));
        z ^= acc.to_bits() & 1;
    }
    acc
}

/// The median wall time of `runs` runs of the chain, ms: `reference/chain_2e22` timed
/// by hand, for a bench to read the machine's speed right beside its own frames (the
/// load can change between criterion's reference and a bench many minutes later).
#[allow(dead_code, reason = "only the benches that time frames by hand call it")]
pub(crate) fn chain_ms_now(runs: usize) -> f64 {
    let mut t: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let start = std::time::Instant::now();
            black_box(chain(black_box(1)));
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Registers the two reference benchmarks.
pub(crate) fn reference(c: &mut Criterion) {
    let mut g = c.benchmark_group("reference");
    g.sample_size(20);
    let src: Vec<f32> = (0..COPY_LEN).map(|i| i as f32).collect();
    let mut dst = vec![0.0f32; COPY_LEN];
    g.bench_function("copy_64mib", |b| {
        b.iter(|| {
            dst.copy_from_slice(black_box(&src));
            black_box(dst[COPY_LEN / 2])
        })
    });
    g.bench_function("chain_2e22", |b| b.iter(|| chain(black_box(1))));
    g.finish();
}
