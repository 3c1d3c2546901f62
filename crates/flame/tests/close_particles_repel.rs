//! Eq (12)'s sign: gas above the reference density pushes particles apart.

use glam::Vec3;
use phenomena_core::kernel::KernelKind;
use phenomena_flame::{FlameConfig, FlameSim, Mode};

#[test]
fn two_close_particles_push_each_other_apart() {
    for kernel in [KernelKind::Spiky, KernelKind::Poly6] {
        let mut config = FlameConfig { mode: Mode::Paper, ..Default::default() };
        config.sph.pressure_kernel = kernel;
        config.sph.rest_density_kg_m3 = 1e-6; // far below the pair's density: p > 0
        config.emitter.rate_per_s = 0.0;
        let d = config.sph.support_radius_m;
        let a = Vec3::new(0.0, 1.0, 0.0);
        let b = a + Vec3::new(0.3 * d, 0.1 * d, 0.0);
        let mut sim = FlameSim::with_particles(config, 1, vec![a, b], vec![Vec3::ZERO; 2]).unwrap();
        sim.evaluate_at(0.0).unwrap();
        let p = sim.particles();
        let (ia, ib) = if p.id[0] == 0 { (0, 1) } else { (1, 0) };
        let away = (b - a).normalize();
        assert!(p.acceleration_m_s2[ib].dot(away) > 0.0, "{kernel:?}: b is pushed away from a");
        assert!(p.acceleration_m_s2[ia].dot(away) < 0.0, "{kernel:?}: a is pushed away from b");
        // Equal masses and densities: equal and opposite (Newton's third law).
        let sum = p.acceleration_m_s2[ia] + p.acceleration_m_s2[ib];
        assert!(sum.length() < 1e-5 * p.acceleration_m_s2[ia].length());
    }
}
