//! `validate` predicts the SPH step's neighbour limit at the burner
//! (`FlameConfig::max_burner_rate_per_s`), so a flame it accepts also renders: just
//! under the predicted rate the simulation runs past its steady state without
//! "too dense", and above it the configuration is refused at `emitter.rate_per_s`.

use phenomena_flame::{FlameConfig, FlameSim};

/// A short-lived gas: the density at the burner is the same as with long lives (it is
/// rate / (π r² v)), with fewer particles to step.
fn config(share_of_limit: f64) -> FlameConfig {
    let mut c = FlameConfig::default();
    c.emitter.lifetime_s = 0.25;
    c.emitter.lifetime_jitter = 0.0;
    let limit = c.max_burner_rate_per_s().expect("a disk burner with upward gas");
    c.emitter.rate_per_s = (share_of_limit * limit) as f32;
    c
}

#[test]
fn just_under_the_predicted_rate_the_flame_runs() {
    let c = config(0.9);
    assert_eq!(c.validate(), Ok(()));
    let mut sim = FlameSim::new(c, 3).unwrap();
    // 0.5 s: two lifetimes, past the steady state at the burner.
    for frame in 0..30 {
        sim.step().unwrap_or_else(|e| panic!("frame {frame}: {e}"));
    }
}

#[test]
fn above_the_predicted_rate_the_configuration_is_refused() {
    let issues = config(1.2).validate().unwrap_err();
    assert_eq!(issues.len(), 1, "{issues:?}");
    assert_eq!(issues[0].field, "emitter.rate_per_s");
    assert!(issues[0].to_string().contains("neighbours"), "{}", issues[0]);
    // The shipped scenes are far from it.
    assert!(FlameConfig::default().max_burner_rate_per_s().unwrap() > 30.0 * 3000.0);
}
