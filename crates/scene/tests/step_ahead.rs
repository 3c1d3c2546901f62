//! A snow scene steps its next frame on a spare copy of the simulation while a frame
//! renders (`Phenomenon::sync_spare`, issue 41). These tests hold the runner to what
//! stepping after each render gives: the same frames and counters as the snow's own
//! simulation and renderer driven one after the other, the checkpoint of each frame
//! its own state (not the next frame's), and a checkpoint restored between frames
//! continuing from itself (the step taken ahead dropped).

use phenomena_core::image::Frame;
use phenomena_scene::checkpoint;
use phenomena_scene::shipped::SHIPPED;
use phenomena_scene::snow::SnowScene;
use phenomena_scene::{Assets, FrameSink, Output, Runner, Scene, SinkError};
use phenomena_snow::{SnowRenderer, SnowSim, SnowState};
use serde_json::Value;

/// Every frame given: its index, image, checkpoint and counters; and how many frames
/// had their next step taken beside their render.
#[derive(Default)]
struct Keep(Vec<(u32, Frame, Vec<u8>, Value)>, usize);

impl FrameSink for Keep {
    fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
        let checkpoint = out.data.checkpoint()?;
        self.0.push((out.index, out.frame.clone(), checkpoint, out.record.counters.clone()));
        self.1 += usize::from(out.record.ahead_ms.is_some());
        Ok(())
    }
}

/// The shipped snow yard, small and heavy: 48² maps, 16 directions, 96x54 pixels, snow
/// falling fast enough to slide off its roofs within the frames drawn, and its
/// probability drawn again every second step (so the spare syncs a changed one).
fn yard() -> Scene {
    let shipped = SHIPPED.iter().find(|s| s.name == "snow-yard").expect("the yard is shipped");
    let mut scene = shipped.scene().unwrap_or_else(|e| panic!("{e}"));
    let file = scene.get_mut::<SnowScene>().expect("a snow scene");
    file.snow.map_resolution = 48;
    file.snow.directions = 16;
    file.snow.shadow_resolution = 64;
    file.snow.rate_cm_per_h = 60.0;
    file.snow.probability_every_steps = 2;
    file.scene.width = 96;
    file.scene.height = 54;
    scene
}

/// Frames `0..frames` through the runner, each rendered.
fn through_runner(scene: &Scene, frames: u32) -> Keep {
    let mut runner = Runner::new(scene, &Assets::none()).expect("builds");
    let mut keep = Keep::default();
    runner.run(0..frames, &mut keep, &mut ()).expect("renders");
    keep
}

#[test]
fn frames_stepped_ahead_are_those_stepped_after_each_render() {
    let scene = yard();
    let frames = 6;
    let kept = through_runner(&scene, frames);
    // The snow's own simulation and renderer, one after the other (no spare).
    let file = scene.get::<SnowScene>().expect("a snow scene");
    let mesh = file.geometry.builtin.expect("a built-in mesh").mesh();
    let mut sim = SnowSim::new(mesh, file.snow.clone(), file.scene.seed).expect("builds");
    let mut renderer = SnowRenderer::new(file.render.clone(), 96, 54, None).expect("renderer");
    assert_eq!(kept.0.len(), frames as usize);
    // Each render took the next frame's step beside it.
    assert_eq!(kept.1, frames as usize);
    for (index, frame, bytes, counters) in &kept.0 {
        let stats = serde_json::to_value(sim.step().expect("steps")).expect("counters");
        assert_eq!(counters, &stats, "frame {index}: the counters");
        assert_eq!(frame, renderer.render(&sim), "frame {index}: the image");
        // The frame's checkpoint holds this frame's state, not the next one's.
        let (header, payload) = checkpoint::open(bytes).expect("a checkpoint");
        let state: SnowState = checkpoint::decode_state(payload).expect("the snow's state");
        assert_eq!(
            (header.frames_done, &state),
            (sim.steps(), &sim.state()),
            "frame {index}: the checkpoint"
        );
    }
    assert!(sim.fallen_off_m3() > 0.0, "the frames should see snow fall off the yard");
}

#[test]
fn a_checkpoint_is_its_frames_and_restoring_one_drops_the_step_taken_ahead() {
    let scene = yard();
    let kept = through_runner(&scene, 6);
    // Checkpoints of consecutive frames differ: each holds its own frame's state.
    for pair in kept.0.windows(2) {
        assert_ne!(pair[0].2, pair[1].2, "frames {} and {}", pair[0].0, pair[1].0);
    }
    // Run to frame 4 (rendered, so frame 5 is stepped ahead), then go back to frame 1.
    let mut runner = Runner::new(&scene, &Assets::none()).expect("builds");
    runner.run(0..5, &mut Keep::default(), &mut ()).expect("renders");
    assert_eq!(runner.restore(&kept.0[1].2).expect("restores"), 2);
    let mut again = Keep::default();
    runner.run(2..6, &mut again, &mut ()).expect("renders");
    assert_eq!(again.0.len(), 4);
    for (a, b) in again.0.iter().zip(&kept.0[2..]) {
        assert_eq!((a.0, &a.1, &a.2, &a.3), (b.0, &b.1, &b.2, &b.3), "frame {} after the restore", a.0);
    }
}
