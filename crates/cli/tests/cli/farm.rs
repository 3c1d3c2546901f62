//! Issue 22: `farm slurm` writes a two-stage Slurm job. Without a cluster, its scripts
//! are run here as Slurm would run them (the simulation, then each array task with its
//! SLURM_ARRAY_TASK_ID, out of order), and the frames must equal one local render. The
//! real Slurm run is `tools/slurm/farm-test.sh` in `.ci/run`.

use std::path::Path;
use std::process::Command;

use crate::{TINY_FLAME, fails, ok, write};

fn bash(script: &Path, task: Option<u32>) {
    let mut cmd = Command::new("bash");
    cmd.arg(script).env_remove("SLURM_ARRAY_TASK_ID").env("SLURM_CPUS_PER_TASK", "1");
    if let Some(i) = task {
        cmd.env("SLURM_ARRAY_TASK_ID", i.to_string());
    }
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{}: {}", script.display(), String::from_utf8_lossy(&out.stderr));
}

#[test]
fn the_farm_scripts_render_the_same_frames_as_one_machine() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny flame.toml", &TINY_FLAME.replace("frames = 4", "frames = 10"));
    let stdout =
        ok(dir.path(), &["farm", "slurm", &scene, "--out", "farm out", "--chunk", "3", "--partition", "gpu"]);
    assert!(stdout.contains("10 frames in 4 task(s) of 3 frames"), "{stdout}");
    let farm = dir.path().join("farm out/farm");
    let render = std::fs::read_to_string(farm.join("render.sbatch")).unwrap();
    for line in ["#SBATCH --array=0-3", "#SBATCH --partition=gpu", "#SBATCH --cpus-per-task=1"] {
        assert!(render.contains(line), "{line} missing:\n{render}");
    }
    let submit = std::fs::read_to_string(farm.join("submit.sh")).unwrap();
    assert!(submit.contains("--dependency=afterok:"), "{submit}");
    // The array task refuses to run outside an array job.
    let out = Command::new("bash")
        .arg(farm.join("render.sbatch"))
        .env_remove("SLURM_ARRAY_TASK_ID")
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("this script is an array job"));

    bash(&farm.join("simulate.sbatch"), None);
    for task in [3, 1, 0, 2] {
        bash(&farm.join("render.sbatch"), Some(task));
    }
    ok(dir.path(), &["render", &scene, "--out", "local"]);
    let names: Vec<String> = (0..10).map(|i| format!("frame_{i:05}.png")).collect();
    for n in &names {
        let farm = std::fs::read(dir.path().join("farm out/frames").join(n)).unwrap();
        let local = std::fs::read(dir.path().join("local").join(n)).unwrap();
        assert!(farm == local, "{n} differs");
    }
    // Each task after the first started from its checkpoint.
    for a in [3, 6, 9] {
        assert!(dir.path().join(format!("farm out/checkpoints/checkpoint_{a:05}.ckpt")).is_file());
    }
}

#[test]
fn submitting_without_slurm_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    let out = assert_cmd::cargo::cargo_bin_cmd!("phenomena")
        .current_dir(dir.path())
        .env("PATH", dir.path())
        .args(["farm", "slurm", &scene, "--out", "o", "--chunk", "2", "--submit"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot run sbatch"), "{stderr}");
    // A bad scene is refused before anything is written.
    let bad = write(dir.path(), "bad.toml", &TINY_FLAME.replace("rate_per_s = 1200.0", "rate_per_s = -1.0"));
    let e = fails(dir.path(), &["farm", "slurm", &bad, "--out", "o2", "--chunk", "2"]);
    assert!(e.contains("bad.toml:") && e.contains("rate_per_s"), "{e}");
    assert!(!dir.path().join("o2").exists());
}
