//! A shot of several phenomena composes them by the rule of `phenomena_scene::shot`:
//! surfaces replace what is behind them, emissive light adds, a surface hides what is
//! behind it, and glints sit in front of or behind the flame by depth. Each case has a
//! known answer computed from the shot's own per-phenomenon layers.

use std::collections::BTreeMap;

use phenomena_core::image::Frame;
use phenomena_scene::{Assets, FrameSink, Output, Runner, Scene, SinkError, parse};

/// The last frame's image and every layer, by channel name.
#[derive(Default)]
struct Keep {
    frame: Option<Frame>,
    layers: BTreeMap<String, Vec<f32>>,
}

impl FrameSink for Keep {
    fn write(&mut self, output: &Output<'_>) -> Result<(), SinkError> {
        self.frame = Some(output.frame.clone());
        self.layers = output.layers.iter().map(|l| (l.name.to_string(), l.plane.data().to_vec())).collect();
        Ok(())
    }
}

/// Render `frames` frames of `text` and keep the last.
fn shot(text: &str, frames: u32) -> (Frame, BTreeMap<String, Vec<f32>>) {
    shot_with(text, frames, &Assets::none())
}

/// [`shot`] reading files through `assets`.
fn shot_with(text: &str, frames: u32, assets: &Assets) -> (Frame, BTreeMap<String, Vec<f32>>) {
    let scene: Scene = parse(text, "shot.toml").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.phenomenon().name(), "shot");
    let mut runner = Runner::new(&scene, assets).unwrap_or_else(|e| panic!("{e}"));
    let mut keep = Keep::default();
    runner.run(0..frames, &mut keep, &mut ()).unwrap_or_else(|e| panic!("{e}"));
    (keep.frame.expect("a frame"), keep.layers)
}

fn plane(frame: &Frame, c: usize) -> &[f32] {
    [&frame.c0, &frame.c1, &frame.c2][c].data()
}

const SIZE: &str = "[scene]\nwidth = 96\nheight = 54\nseed = 2\n";

/// A camera 6 m south of the built-in table, looking north and a little up: the table
/// (and its ground) fill the lower part, the sky the upper.
const CAMERA: &str = "[render.camera]\nposition = [0.0, 1.0, -6.0]\nlook_at = [0.0, 2.5, 0.0]\nprojection = { kind = \"perspective\", fov_y_deg = 60.0 }\n";

const SNOW: &str = "[geometry]\nbuiltin = \"table\"\n[snow]\nmap_resolution = 32\ndirections = 8\n";

const AURORA: &str = "[aurora.motion]\nparticles = 4000\n[render.aurora.sky]\nstars = true\n";

/// Surfaces replace: where the snow's scene covers a pixel the shot shows exactly the
/// snow's image (no aurora or star light leaks through the table and the ground);
/// elsewhere exactly the aurora's sky.
#[test]
fn a_surface_in_front_of_the_aurora_hides_it() {
    // The camera low (20 cm up), so the table stands against the sky: above the horizon,
    // where the airglow and the stars are, the table hides sky light.
    let camera = CAMERA.replace("position = [0.0, 1.0, -6.0]", "position = [0.0, 0.2, -6.0]");
    let text = format!("{SIZE}{camera}[render]\naurora_site_km = [0.0, -100.0]\n{SNOW}{AURORA}");
    let (beauty, layers) = shot(&text, 3);
    let cover = &layers["snow.A"];
    let (mut covered, mut open, mut sky_lit) = (0, 0, 0);
    for c in 0..3 {
        let name = ["R", "G", "B"][c];
        let (snow, aurora) = (&layers[&format!("snow.{name}")], &layers[&format!("aurora.{name}")]);
        for (k, &b) in plane(&beauty, c).iter().enumerate() {
            if cover[k] == 1.0 {
                assert_eq!(b, snow[k], "pixel {k}: a surface shows itself alone");
                covered += 1;
            } else {
                assert_eq!(cover[k], 0.0);
                assert_eq!(b, aurora[k], "pixel {k}: the open sky shows the aurora's light");
                assert_eq!(snow[k], 0.0);
                open += 1;
                sky_lit += usize::from(aurora[k] > 0.0);
            }
        }
    }
    assert!(covered > 0 && open > 0, "the camera sees both: {covered} covered, {open} open");
    assert!(sky_lit > 0, "the aurora or the stars light some open sky");
    // And the aurora does light pixels the surfaces then cover (so the test hides light).
    let hidden = (0..3)
        .flat_map(|c| {
            let name = ["R", "G", "B"][c];
            let aurora = layers[&format!("aurora.{name}")].clone();
            aurora.into_iter().zip(cover.clone())
        })
        .filter(|&(a, cover)| a > 0.0 && cover == 1.0)
        .count();
    assert!(hidden > 0, "no aurora light lay behind a surface: the case tests nothing");
}

/// The flame over the table, its shimmer off: the shot is the snow's image plus the
/// flame's light, pixel by pixel (what is behind the flame is seen through it), and the
/// flame's light reaches the image.
#[test]
fn an_object_behind_the_flame_is_seen_through_it() {
    let flame = "[flame]\n[flame.emitter]\nposition_m = [0.0, 0.0, -3.0]\n[flame.domain]\nmin_m = [-2.0, -0.5, -5.0]\nmax_m = [2.0, 3.0, -1.0]\n[render.flame.shimmer]\nenabled = false\n";
    let text = format!("{SIZE}{CAMERA}{SNOW}{flame}");
    let (beauty, layers) = shot(&text, 30);
    let mut lit = 0;
    for c in 0..3 {
        let name = ["R", "G", "B"][c];
        let (snow, fire) = (&layers[&format!("snow.{name}")], &layers[&format!("flame.{name}")]);
        let cover = &layers["snow.A"];
        for (k, &b) in plane(&beauty, c).iter().enumerate() {
            if cover[k] == 1.0 {
                // The snow's image there is the table or the ground, behind the flame.
                assert_eq!(b, snow[k] + fire[k], "pixel {k}");
                lit += usize::from(fire[k] > 0.0);
            }
        }
    }
    assert!(lit > 0, "the flame's light reached pixels with a surface behind it");
}

/// A wall between the camera and the flame: every splat is behind it, so the flame's
/// light is exactly none; without the wall (the same flame beside diamond dust) it is
/// seen.
#[test]
fn a_wall_in_front_of_the_flame_hides_it() {
    let dir = tempfile::tempdir().unwrap();
    // A 6 m x 5 m wall across the view 1.5 m north of the flame's side, on a ground.
    let obj = "v -3 -1 -1.5\nv 3 -1 -1.5\nv 3 4 -1.5\nv -3 4 -1.5\nv -6 0 -8\nv 6 0 -8\nv 6 0 6\nv -6 0 6\nf 1 2 3\nf 1 3 4\nf 5 7 6\nf 5 8 7\n";
    std::fs::write(dir.path().join("wall.obj"), obj).unwrap();
    let camera = "[render.camera]\nposition = [0.0, 1.0, 4.0]\nlook_at = [0.0, 0.8, -3.0]\nprojection = { kind = \"perspective\", fov_y_deg = 40.0 }\n";
    let flame = "[flame]\n[flame.emitter]\nposition_m = [0.0, 0.0, -3.0]\n[flame.domain]\nmin_m = [-2.0, -0.5, -5.0]\nmax_m = [2.0, 3.0, -1.0]\n[render.flame.shimmer]\nenabled = false\n";
    let walled = format!(
        "{SIZE}{camera}[geometry]\nmesh = \"wall.obj\"\n[snow]\nmap_resolution = 32\ndirections = 8\n{flame}"
    );
    let open = format!(
        "{SIZE}{camera}{flame}[sparkle]\nfps = 60.0\n[sparkle.population]\nkind = \"diamond-dust\"\ndensity_per_m3 = 1.0\n"
    );
    let file = dir.path().join("walled.toml");
    std::fs::write(&file, &walled).unwrap();
    let (_, behind) = shot_with(&walled, 20, &Assets::beside(&file));
    let (_, alone) = shot(&open, 20);
    let light = |layers: &BTreeMap<String, Vec<f32>>| -> f64 {
        ["R", "G", "B"].iter().flat_map(|c| layers[&format!("flame.{c}")].iter()).map(|&v| f64::from(v)).sum()
    };
    assert!(light(&alone) > 0.0, "the flame alone is seen");
    assert_eq!(light(&behind), 0.0, "the wall hides every splat");
    assert!(behind["snow.A"].contains(&1.0), "the wall is seen");
}

/// Diamond dust around a flame, shimmer on: the glints nearer than the flame are added
/// after it (unrefracted), the farther ones before it; with no glint on either side the
/// shot is the flame alone. Here: every glint's light is in the sparkle layer and the
/// shot adds exactly the flame's light to it where there is no shimmer.
#[test]
fn glints_are_added_in_front_of_and_behind_the_flame() {
    let flame = "[flame]\n[flame.emitter]\nposition_m = [0.0, 0.0, -3.0]\n[flame.domain]\nmin_m = [-2.0, -0.5, -5.0]\nmax_m = [2.0, 3.0, -1.0]\n[render.flame.shimmer]\nenabled = false\n";
    let dust = "[sparkle]\nfps = 60.0\n[sparkle.population]\nkind = \"diamond-dust\"\nbox_min_m = [-6.0, 0.0, -6.0]\nbox_max_m = [6.0, 5.0, 3.0]\ndensity_per_m3 = 20000.0\n[render.sparkle]\nglare = \"none\"\nbackground = { kind = \"black\" }\n";
    let text = format!("{SIZE}{CAMERA}{flame}{dust}");
    let (beauty, layers) = shot(&text, 10);
    let mut glints = 0;
    for c in 0..3 {
        let name = ["R", "G", "B"][c];
        let (fire, dust) = (&layers[&format!("flame.{name}")], &layers[&format!("sparkle.{name}")]);
        for (k, &b) in plane(&beauty, c).iter().enumerate() {
            // Black behind, no shimmer: the glints behind, the flame, the glints in front.
            let expected = fire[k] + dust[k];
            assert!((b - expected).abs() <= 1e-6 * expected.abs().max(1.0), "pixel {k}: {b} vs {expected}");
            glints += usize::from(dust[k] > 0.0);
        }
    }
    assert!(glints > 0, "some glints were seen");
}

/// A shot's checkpoint holds every phenomenon: frames rendered from a checkpoint at
/// frame 4 equal those of one run.
#[test]
fn a_shot_resumes_from_a_checkpoint_bit_for_bit() {
    let text = format!(
        "{SIZE}{CAMERA}{SNOW}{AURORA}[flame]\n[flame.emitter]\nposition_m = [0.0, 0.0, -3.0]\n[flame.domain]\nmin_m = [-2.0, -0.5, -5.0]\nmax_m = [2.0, 3.0, -1.0]\n[sparkle]\nfps = 60.0\n"
    );
    let scene = parse(&text, "shot.toml").unwrap();
    let mut one = Runner::new(&scene, &Assets::none()).unwrap();
    let mut keep = Keep::default();
    one.run(0..4, &mut keep, &mut ()).unwrap();
    let saved = one.checkpoint().unwrap();
    one.run(4..8, &mut keep, &mut ()).unwrap();
    let straight = keep.frame.take().unwrap();
    let mut again = Runner::new(&scene, &Assets::none()).unwrap();
    assert_eq!(again.restore(&saved).unwrap(), 4);
    again.run(4..8, &mut keep, &mut ()).unwrap();
    assert_eq!(keep.frame.unwrap(), straight);
}

/// What a shot's phenomena take from it they must not set themselves, and a render
/// table needs its phenomenon: each refused at its place.
#[test]
fn a_shot_refuses_cameras_of_its_own_and_orphan_tables() {
    let text = "[flame]\n[sparkle]\nfps = 30.0\n[sparkle.camera]\nposition = [1.0, 2.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nprojection = { kind = \"perspective\", fov_y_deg = 40.0 }\n[render.snow]\nfog_per_m = 0.1\n";
    let Err(e) = parse(text, "s.toml") else { panic!("accepted") };
    let messages: Vec<String> = e.0.iter().map(ToString::to_string).collect();
    assert!(
        messages.iter().any(|m| m.starts_with("s.toml:3:7: sparkle.fps = 30") && m.contains("one clock")),
        "{messages:?}"
    );
    assert!(
        messages.iter().any(|m| m.contains("sparkle.camera") && m.contains("[render.camera]")),
        "{messages:?}"
    );
    assert!(messages.iter().any(|m| m.contains("render.snow") && m.contains("[snow]")), "{messages:?}");
}

/// The shipped winter night: each of the four phenomena reaches the camera (its layer
/// holds light), the snow covers part of the frame, and the EXR's layers name each.
#[test]
fn the_winter_night_shows_all_four() {
    let shipped = phenomena_scene::shipped::shipped("winter-night").expect("shipped");
    let mut scene = shipped.scene().unwrap_or_else(|e| panic!("{e}"));
    let s = scene.settings_mut();
    (s.width, s.height) = (160, 90);
    let mut runner = Runner::new(&scene, &Assets::none()).unwrap_or_else(|e| panic!("{e}"));
    let mut keep = Keep::default();
    runner.run(0..30, &mut keep, &mut ()).unwrap_or_else(|e| panic!("{e}"));
    let layers = keep.layers;
    for name in ["aurora", "snow", "sparkle", "flame"] {
        let light: f64 =
            ["R", "G", "B"].iter().flat_map(|c| &layers[&format!("{name}.{c}")]).map(|&v| f64::from(v)).sum();
        assert!(light > 0.0, "{name} is not seen");
    }
    let cover = layers["snow.A"].iter().filter(|&&c| c == 1.0).count();
    assert!(cover > 160 * 90 / 10 && cover < 160 * 90, "the village covers part of the frame: {cover}");
    assert!(layers.keys().any(|k| k.starts_with("aurora_")), "the aurora's line layers: {:?}", layers.keys());
}

/// A shot's `vdb` frames hold its flame's volumes (in the shot's metres); a shot with
/// no phenomenon that has volumes is refused before its first frame, by name.
#[test]
fn a_shot_writes_its_flames_volumes_or_says_it_has_none() {
    use phenomena_scene::job::{self, Job};
    use phenomena_scene::{Format, Limits};
    let dir = tempfile::tempdir().unwrap();
    let vdb = Format::named("vdb").expect("registered");
    let flame = "[flame]\n[sparkle]\nfps = 60.0\n";
    let scene = parse(&format!("{SIZE}{flame}"), "s.toml").unwrap_or_else(|e| panic!("{e}"));
    let out = dir.path().join("fire");
    let mut job = Job::new(&out, vdb);
    job.frames = Some(4..6);
    job::render(scene, &Assets::none(), &Limits::NONE, &job, &mut ()).unwrap_or_else(|e| panic!("{e}"));
    let manifest = std::fs::read_to_string(out.join("frame_00005.vdb.json")).expect("a manifest");
    assert!(manifest.contains("\"temperature\"") && manifest.contains("\"density\""), "{manifest}");
    let cold = parse(&format!("{SIZE}{SNOW}[sparkle]\n"), "s.toml").unwrap();
    let out = dir.path().join("cold");
    let e = job::render(cold, &Assets::none(), &Limits::NONE, &Job::new(&out, vdb), &mut ()).unwrap_err();
    assert!(e.to_string().contains("no phenomenon with volumes"), "{e}");
    assert!(std::fs::read_dir(&out).map_or(true, |mut d| d.next().is_none()), "nothing written");
}

/// A ticking clock: every reading 1 ms later than the one before.
struct Ticks(std::sync::atomic::AtomicU64);

impl phenomena_core::clock::Clock for Ticks {
    fn now_ms(&self) -> f64 {
        self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed) as f64
    }
}

/// The frames' records, kept.
#[derive(Default)]
struct Records(Vec<phenomena_scene::FrameRecord>);

impl phenomena_scene::Observer for Records {
    fn frame(&mut self, record: &phenomena_scene::FrameRecord) -> std::ops::ControlFlow<()> {
        self.0.push(record.clone());
        std::ops::ControlFlow::Continue(())
    }
}

/// Given a clock, a shot times each phenomenon: its step (`step_ms` in its counters),
/// and its part of the render (`render_ms` in the render detail, with the aurora's and
/// the snow's own breakdowns beside it); the parts' render times add up to no more than
/// the whole's.
#[test]
fn a_shot_times_each_phenomenon() {
    let text = format!("{SIZE}{CAMERA}{SNOW}{AURORA}");
    let scene = parse(&text, "shot.toml").unwrap();
    let mut runner = Runner::new(&scene, &Assets::none()).unwrap();
    runner.set_clock(phenomena_core::clock::SharedClock::new(Ticks(0.into())));
    let mut records = Records::default();
    runner.run(1..3, &mut Keep::default(), &mut records).unwrap();
    // (Frame 0 is stepped and reported, not rendered.)
    let rendered: Vec<_> = records.0.iter().filter(|r| r.render_ms.is_some()).collect();
    assert_eq!(rendered.len(), 2);
    for r in rendered {
        let detail = r.render_detail.as_ref().expect("a shot's render detail");
        let mut parts = 0.0;
        for name in ["aurora", "snow"] {
            let step =
                r.counters[name]["step_ms"].as_f64().unwrap_or_else(|| panic!("{name}'s step_ms: {r:?}"));
            assert!(step >= 1.0, "{name} step {step}");
            let ms =
                detail[name]["render_ms"].as_f64().unwrap_or_else(|| panic!("{name}'s render_ms: {detail}"));
            assert!(ms >= 1.0, "{name} render {ms}");
            parts += ms;
        }
        // The aurora's and the snow's renderers were given the clock too: their own
        // breakdowns are there.
        assert!(detail["aurora"]["emit_ms"].as_f64().is_some_and(|ms| ms >= 1.0), "{detail}");
        // The snow's parts lie within its render: none timed outside it or twice.
        let mut snow = 0.0;
        for part in ["mesh_ms", "raster_ms", "shadow_ms", "shade_ms", "glitter_ms", "flakes_ms"] {
            let ms = detail["snow"][part].as_f64().unwrap_or_else(|| panic!("snow {part}: {detail}"));
            assert!(ms >= 1.0, "snow {part} {ms}");
            snow += ms;
        }
        let whole = detail["snow"]["render_ms"].as_f64().expect("snow's render_ms");
        assert!(snow <= whole, "snow's parts {snow} ms, its render {whole} ms");
        assert!(detail["snow"]["triangles"].as_u64().is_some_and(|n| n > 0), "{detail}");
        assert!(detail["snow"]["glints"].as_u64().is_some(), "{detail}");
        let whole = r.render_ms.expect("rendered");
        assert!(parts <= whole, "parts {parts} ms, whole {whole} ms");
    }
}
