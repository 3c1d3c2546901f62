//! The symmetrised pressure force of eq (12) is antisymmetric in each pair once divided
//! by ρ_i (eq 8), so Σ_i m_i a_i = 0: the gas cannot push itself anywhere.

use glam::Vec3;
use phenomena_core::kernel::{Dim, Kernel, KernelKind};
use phenomena_core::rng::{Purpose, Stream};
use phenomena_flame::{FlameConfig, FlameSim, Mode};

fn check(kernel: KernelKind) {
    let mut config = FlameConfig { mode: Mode::Paper, ..Default::default() };
    config.sph.pressure_kernel = kernel;
    config.sph.gas_constant_m2_s2 = 3.0;
    let d = config.sph.support_radius_m;
    // A random, uneven cloud: dense core, sparse halo, so pressures differ in sign.
    let mut rng = Stream::new(3, Purpose::named("test.cloud"), 0);
    let positions: Vec<Vec3> =
        (0..4000).map(|_| rng.on_unit_sphere() * (0.2 * rng.next_f32().powf(0.7))).collect();
    let n = positions.len();
    let mut sim = FlameSim::with_particles(config.clone(), 1, positions, vec![Vec3::ZERO; n]).unwrap();
    sim.evaluate_at(0.0).unwrap();
    let p = sim.particles();

    let total: Vec3 = (0..n).map(|i| p.acceleration_m_s2[i] * p.mass_kg[i]).sum();
    // Error model: each a_i is an f32 sum of its pair terms, rounded with relative error
    // at most k·ε (k = neighbour count, ε = 2^-24), so |Σ m_i a_i| ≤ k_max·ε·Σ|pair terms|.
    let w = Kernel::new(kernel, Dim::Three, d);
    let mut scale = 0.0f64;
    let mut k_max = 0usize;
    for i in 0..n {
        let mut k = 0;
        for j in 0..n {
            let r = p.position_m[i] - p.position_m[j];
            let len = r.length();
            if i != j && len < d {
                k += 1;
                let term = p.mass_kg[i] * p.mass_kg[j] * (p.pressure_pa[i] + p.pressure_pa[j])
                    / (2.0 * p.density_kg_m3[i] * p.density_kg_m3[j])
                    * w.gradient_factor(len)
                    * len;
                scale += f64::from(term.abs());
            }
        }
        k_max = k_max.max(k);
    }
    let bound = k_max as f64 * f64::from(f32::EPSILON) * scale;
    assert!(scale > 0.0 && k_max > 10, "the cloud must interact (k_max {k_max})");
    for c in total.to_array() {
        assert!(
            f64::from(c.abs()) <= bound,
            "{kernel:?}: Σ m a = {total:?}, bound {bound:e}, scale {scale:e}"
        );
    }
}

#[test]
fn spiky_pressure_force_sums_to_zero() {
    check(KernelKind::Spiky);
}

#[test]
fn poly6_pressure_force_sums_to_zero() {
    check(KernelKind::Poly6);
}
