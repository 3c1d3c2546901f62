//! Determinism: the same scene and seed give bit-identical particles and images with one
//! worker thread or several.

use phenomena_flame::{FlameConfig, FlameRenderer, FlameSim, RenderSettings};

fn run(threads: usize) -> (phenomena_flame::FlameState, Vec<f32>) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let mut config = FlameConfig::default();
        config.emitter.rate_per_s = 6000.0; // enough particles for many parallel chunks
        let mut sim = FlameSim::new(config, 42).unwrap();
        for _ in 0..45 {
            sim.step().unwrap();
        }
        for scale in [1.0, 0.5] {
            let settings = RenderSettings { resolution_scale: scale, ..Default::default() };
            let mut r = FlameRenderer::new(settings, 200, 120, None).unwrap();
            let _ = r.render(&sim);
        }
        let settings = RenderSettings { resolution_scale: 0.5, ..Default::default() };
        let mut r = FlameRenderer::new(settings, 200, 120, None).unwrap();
        let frame = r.render(&sim).to_interleaved();
        (sim.state(), frame)
    })
}

#[test]
fn one_and_three_threads_agree_bit_for_bit() {
    let (state1, image1) = run(1);
    let (state3, image3) = run(3);
    assert!(state1.particles.len() > 3000);
    assert_eq!(state1, state3);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&image1), bits(&image3));
}
