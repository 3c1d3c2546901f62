//! Test statistics for comparing the stochastic model with brute force: the chi-square
//! survival function, the two-sample chi-square test of homogeneity and the two-sample
//! Kolmogorov-Smirnov test (Numerical Recipes in C, 2nd ed., §6.2 and §14.3).

#![allow(dead_code)]

/// ln Γ(x) for x > 0 (Lanczos, NR `gammln`, |error| < 2e-10).
pub(crate) fn ln_gamma(x: f64) -> f64 {
    const COF: [f64; 6] = [
        76.180_091_729_471_46,
        -86.505_320_329_416_77,
        24.014_098_240_830_91,
        -1.231_739_572_450_155,
        0.120_865_097_386_617_9e-2,
        -0.539_523_938_495_3e-5,
    ];
    let mut y = x;
    let tmp = x + 5.5;
    let tmp = tmp - (x + 0.5) * tmp.ln();
    let mut ser = 1.000_000_000_190_015;
    for c in COF {
        y += 1.0;
        ser += c / y;
    }
    -tmp + (2.506_628_274_631_000_5 * ser / x).ln()
}

/// Regularised upper incomplete gamma Q(a, x) (NR `gammq`: series below a + 1,
/// continued fraction above).
pub(crate) fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        let (mut ap, mut sum) = (a, 1.0 / a);
        let mut del = sum;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// P(χ² ≥ x) with k degrees of freedom.
pub(crate) fn chi2_sf(x: f64, k: f64) -> f64 {
    gamma_q(0.5 * k, 0.5 * x)
}

/// Two-sample chi-square test that counts `r` and `s` over the same bins come from one
/// distribution (NR `chstwo` with unequal totals). Bins whose expected count in either
/// sample is below 5 are pooled into one bin first. Returns (statistic, degrees of
/// freedom, p-value).
pub(crate) fn chi2_two_sample(r: &[u64], s: &[u64]) -> (f64, f64, f64) {
    let (rt, st) = (r.iter().sum::<u64>() as f64, s.iter().sum::<u64>() as f64);
    let mut bins: Vec<(f64, f64)> = Vec::new();
    let mut pooled = (0.0, 0.0);
    for (&a, &b) in r.iter().zip(s) {
        let total = (a + b) as f64;
        let (er, es) = (total * rt / (rt + st), total * st / (rt + st));
        if er < 5.0 || es < 5.0 {
            pooled.0 += a as f64;
            pooled.1 += b as f64;
        } else {
            bins.push((a as f64, b as f64));
        }
    }
    if pooled.0 + pooled.1 > 0.0 {
        bins.push(pooled);
    }
    let (k1, k2) = ((st / rt).sqrt(), (rt / st).sqrt());
    let chi: f64 = bins.iter().map(|&(a, b)| (k1 * a - k2 * b).powi(2) / (a + b)).sum();
    let df = bins.len() as f64 - 1.0;
    (chi, df, chi2_sf(chi, df))
}

/// Q_KS(λ) = 2 Σ (-1)^(j-1) exp(-2 j² λ²) (NR `probks`).
pub(crate) fn q_ks(lambda: f64) -> f64 {
    let a2 = -2.0 * lambda * lambda;
    let (mut fac, mut sum, mut termbf) = (2.0, 0.0, 0.0f64);
    for j in 1..=100 {
        let term = fac * (a2 * (j * j) as f64).exp();
        sum += term;
        if term.abs() <= 1e-3 * termbf || term.abs() <= 1e-8 * sum {
            return sum.clamp(0.0, 1.0);
        }
        fac = -fac;
        termbf = term.abs();
    }
    1.0
}

/// Two-sample Kolmogorov-Smirnov test (NR `kstwo`): (D, p-value). With discrete data
/// (lifetimes in whole frames) the p-value is conservative: larger than the exact one.
pub(crate) fn ks_two_sample(a: &[f64], b: &[f64]) -> (f64, f64) {
    let mut a = a.to_vec();
    let mut b = b.to_vec();
    a.sort_by(f64::total_cmp);
    b.sort_by(f64::total_cmp);
    let (n1, n2) = (a.len() as f64, b.len() as f64);
    let (mut j1, mut j2) = (0usize, 0usize);
    let mut d = 0.0f64;
    while j1 < a.len() && j2 < b.len() {
        let (d1, d2) = (a[j1], b[j2]);
        if d1 <= d2 {
            while j1 < a.len() && a[j1] == d1 {
                j1 += 1;
            }
        }
        if d2 <= d1 {
            while j2 < b.len() && b[j2] == d2 {
                j2 += 1;
            }
        }
        d = d.max((j1 as f64 / n1 - j2 as f64 / n2).abs());
    }
    let ne = (n1 * n2 / (n1 + n2)).sqrt();
    (d, q_ks((ne + 0.12 + 0.11 / ne) * d))
}

#[test]
fn statistics_match_tabulated_values() {
    // Critical values from standard tables: χ²(1) 3.841 and χ²(10) 18.307 at 5 %,
    // χ²(100) 135.807 at 1 %; Kolmogorov 1.358 at 5 %.
    assert!((chi2_sf(3.841, 1.0) - 0.05).abs() < 2e-4);
    assert!((chi2_sf(18.307, 10.0) - 0.05).abs() < 2e-4);
    assert!((chi2_sf(135.807, 100.0) - 0.01).abs() < 1e-4);
    assert!((q_ks(1.358) - 0.05).abs() < 1e-3);
    assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-9);
    // Identical samples: no evidence against equality; shifted ones: overwhelming.
    let a: Vec<f64> = (0..1000).map(|i| f64::from(i % 17)).collect();
    assert!(ks_two_sample(&a, &a).1 > 0.99);
    let b: Vec<f64> = a.iter().map(|x| x + 3.0).collect();
    assert!(ks_two_sample(&a, &b).1 < 1e-6);
    let r = [100, 200, 300, 2, 1];
    assert!(chi2_two_sample(&r, &r).2 > 0.99);
    assert!(chi2_two_sample(&r, &[300, 200, 100, 2, 1]).2 < 1e-6);
}
