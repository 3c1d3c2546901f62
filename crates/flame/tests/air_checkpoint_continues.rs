//! With the air on, a checkpoint carries the air: continuing from it is bit-identical to
//! not stopping, and the paper mode never has air.
use phenomena_flame::{FlameConfig, FlameSim, Mode};

#[test]
fn a_checkpoint_with_air_continues_bit_identically() {
    let mut c = FlameConfig::default();
    c.extended.air.enabled = true;
    c.extended.air.cells_per_diameter = 8;
    let mut a = FlameSim::new(c.clone(), 3).expect("valid");
    for _ in 0..20 {
        a.step().expect("step");
    }
    let state = a.state();
    assert!(state.air.is_some());
    let mut b = FlameSim::from_state(c.clone(), 3, state.clone()).expect("restore");
    for _ in 0..10 {
        a.step().expect("step");
        b.step().expect("step");
    }
    assert_eq!(a.state(), b.state());
    // The air moved: its state is not the fresh one.
    assert_ne!(a.state().air, FlameSim::new(c.clone(), 3).expect("valid").state().air);

    // A checkpoint without air is refused by a simulation with air, naming why.
    let mut no_air = state;
    no_air.air = None;
    let err = FlameSim::from_state(c, 3, no_air).expect_err("no air in the checkpoint");
    assert!(err.to_string().contains("no air"), "{err}");
}

#[test]
fn the_paper_mode_has_no_air() {
    let mut c = FlameConfig { mode: Mode::Paper, ..Default::default() };
    c.extended.air.enabled = true;
    let sim = FlameSim::new(c, 1).expect("valid");
    assert!(sim.air().is_none());
    assert!(sim.state().air.is_none());
}

#[test]
fn a_checkpoint_with_broken_air_is_refused_and_changes_nothing() {
    let mut c = FlameConfig::default();
    c.extended.air.enabled = true;
    c.extended.air.cells_per_diameter = 8;
    let mut sim = FlameSim::new(c, 3).expect("valid");
    for _ in 0..5 {
        sim.step().expect("step");
    }
    let before = sim.state();
    let mut nan = before.clone();
    nan.air.as_mut().expect("air").drift[3][0] = f32::NAN;
    let err = sim.restore(nan).expect_err("a drift that is not finite");
    assert!(err.to_string().contains("not finite"), "{err}");
    let mut cold = before.clone();
    cold.air.as_mut().expect("air").theta[0] = -400.0;
    let err = sim.restore(cold).expect_err("air colder than ambient");
    assert!(err.to_string().contains("below ambient"), "{err}");
    assert_eq!(sim.state(), before);
}

#[test]
fn the_air_needs_an_ambient_above_absolute_zero() {
    let mut c = FlameConfig::default();
    c.extended.air.enabled = true;
    c.extended.ambient_temperature_k = 0.0;
    let errs = c.validate().expect_err("0 K with the air on");
    assert!(errs.iter().any(|e| e.field == "extended.ambient_temperature_k"), "{errs:?}");
    c.extended.air.enabled = false;
    assert_eq!(c.validate(), Ok(()));
}
