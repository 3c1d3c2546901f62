//! The contract every registered phenomenon keeps, checked by looping over the
//! registry (a new phenomenon or output format is covered by its registry line alone):
//! every format it offers writes its frames and resumes, every format it does not is
//! refused by name; chunks rendered from checkpoints equal one render; the bytes do not
//! depend on the thread count.

use std::path::Path;

use phenomena_scene::job::{self, Done, Job, JobError};
use phenomena_scene::registry::{FORMATS, PHENOMENA};
use phenomena_scene::{Assets, Entry, Format, Limits, Scene};

/// Phenomenon `p`'s default scene, small: 48 × 27 pixels, `frames` frames.
fn small(p: Entry, frames: u32) -> Scene {
    let mut scene = p.default_scene();
    let s = scene.settings_mut();
    (s.width, s.height, s.frames) = (48, 27, frames);
    scene
}

fn render(scene: &Scene, job: &Job) -> Result<Done, JobError> {
    job::render(scene.clone(), &Assets::none(), &Limits::NONE, job, &mut ())
}

/// Every file in `dir` whose name starts with `frame_` or `flipbook`, sorted, with its
/// bytes.
fn outputs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.starts_with("frame_") || n.starts_with("flipbook")
        })
        .map(|e| (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).unwrap()))
        .collect();
    out.sort();
    out
}

#[test]
fn every_phenomenon_is_written_in_every_format_it_offers_and_refused_in_the_others() {
    let dir = tempfile::tempdir().unwrap();
    for &p in PHENOMENA {
        let scene = small(p, 3);
        for &f in FORMATS {
            let out = dir.path().join(format!("{}-{}", p.name(), f.name()));
            let result = render(&scene, &Job::new(&out, f));
            if !f.writes(p) {
                let Err(JobError::Refused(e)) = result else { panic!("{} as {f}: not refused", p.name()) };
                let offered: Vec<String> = Format::of(p).iter().map(|f| f.name().to_string()).collect();
                assert!(e.contains(&format!("not written as {f}")) && e.contains(&offered.join(", ")), "{e}");
                assert!(!out.exists(), "{} as {f}: files written", p.name());
                continue;
            }
            let done = result.unwrap_or_else(|e| panic!("{} as {f}: {e}", p.name()));
            assert!(done.lines[0].starts_with("wrote"), "{} as {f}: {:?}", p.name(), done.lines);
            let written = outputs(&out);
            assert!(!written.is_empty() && written.iter().all(|(_, b)| !b.is_empty()), "{} as {f}", p.name());
            // A second run with resume keeps every frame, or is refused with the reason.
            let again = render(&scene, &Job { resume: true, ..Job::new(&out, f) });
            match again {
                Ok(done) => {
                    assert!(f.resumable() && done.lines[0].contains("kept 3 finished"), "{:?}", done.lines)
                }
                Err(e) => assert!(!f.resumable() && e.to_string().contains("--resume"), "{e}"),
            }
            assert_eq!(outputs(&out), written, "{} as {f}: resume changed the files", p.name());
        }
    }
}

#[test]
fn every_phenomenon_renders_from_its_checkpoints_what_one_render_makes() {
    let dir = tempfile::tempdir().unwrap();
    let png = FORMATS[0];
    for &p in PHENOMENA {
        let scene = small(p, 6);
        let whole = dir.path().join(format!("{}-whole", p.name()));
        let ckpt = dir.path().join(format!("{}-ckpt", p.name()));
        let job =
            Job { checkpoint_every: Some(3), checkpoint_dir: Some(ckpt.clone()), ..Job::new(&whole, png) };
        render(&scene, &job).unwrap();
        let part = dir.path().join(format!("{}-part", p.name()));
        let job = Job { frames: Some(3..6), checkpoint_dir: Some(ckpt), ..Job::new(&part, png) };
        let done = render(&scene, &job).unwrap();
        assert_eq!(done.started_at, 3, "{}: {:?}", p.name(), done.lines);
        assert_eq!(outputs(&part), outputs(&whole)[3..], "{}: frames from the checkpoint differ", p.name());
    }
}

#[test]
fn every_phenomenon_writes_the_same_bytes_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    for &p in PHENOMENA {
        let scene = small(p, 3);
        let run = |threads: usize| {
            let out = dir.path().join(format!("{}-{threads}", p.name()));
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| render(&scene, &Job::new(&out, FORMATS[1]))).unwrap();
            outputs(&out)
        };
        assert_eq!(run(1), run(3), "{}: the thread count changed the EXR frames", p.name());
    }
}

/// A view's name is written where the registry lists it and where the scene file holds
/// it: every view of every phenomenon round-trips through `set_view`, is what the
/// scene's `[render] view` says (where it has one), and renders.
#[test]
fn every_view_of_every_phenomenon_round_trips_and_renders() {
    let dir = tempfile::tempdir().unwrap();
    for &p in PHENOMENA {
        for view in p.views() {
            let mut scene = small(p, 1);
            scene.set_view(view.name).unwrap();
            assert_eq!(scene.view(), view.name, "{}", p.name());
            if let Some(written) = scene.to_json()["render"].get("view") {
                assert_eq!(written, view.name, "{}: [render] view", p.name());
            }
            let out = dir.path().join(format!("{}-{}", p.name(), view.name));
            render(&scene, &Job::new(&out, FORMATS[0]))
                .unwrap_or_else(|e| panic!("{} {}: {e}", p.name(), view.name));
            assert_eq!(outputs(&out).len(), 1, "{} {}", p.name(), view.name);
        }
        assert!(small(p, 1).set_view("no-such-view").is_err());
    }
}
