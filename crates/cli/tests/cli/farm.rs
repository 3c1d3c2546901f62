//! `farm slurm` writes a two-stage Slurm job. Without a cluster, its scripts
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

/// Run `script` with bash as a Slurm node would, `PATH` holding only the stubs in
/// `stubs`, and every simple command the script runs logged (a `DEBUG` trap set through
/// `BASH_ENV`); returns the commands.
fn traced(script: &Path, stubs: &Path, task: Option<u32>) -> Vec<String> {
    let log = stubs.join(format!("trace-{}.log", script.file_name().unwrap().to_string_lossy()));
    let env = stubs.join("trace.sh");
    // BASH_ENV is unset first: the stubs (bash scripts too) must not trace themselves.
    std::fs::write(
        &env,
        format!("unset BASH_ENV\ntrap 'printf \"%s\\0\" \"$BASH_COMMAND\" >> \"{}\"' DEBUG\n", log.display()),
    )
    .unwrap();
    let mut cmd = Command::new("/bin/bash");
    cmd.arg(script)
        .current_dir(stubs.parent().unwrap())
        .env_clear()
        .env("PATH", stubs)
        .env("BASH_ENV", &env)
        .env("SLURM_CPUS_PER_TASK", "1")
        .env("STUB_LOG", stubs.join("calls.log"));
    if let Some(i) = task {
        cmd.env("SLURM_ARRAY_TASK_ID", i.to_string());
    }
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{}: {}", script.display(), String::from_utf8_lossy(&out.stderr));
    // One record per command, NUL-terminated (a command's text may hold newlines).
    std::fs::read_to_string(&log).unwrap_or_default().split_terminator('\0').map(str::to_string).collect()
}

/// The `#SBATCH` options sbatch reads from `script`: the `#SBATCH` lines before the
/// first line that is neither a comment nor blank (sbatch stops reading there).
fn sbatch_options(script: &str) -> Vec<String> {
    let mut options = Vec::new();
    for line in script.lines().skip(1) {
        if let Some(rest) = line.strip_prefix("#SBATCH") {
            options.push(rest.trim().to_string());
        } else if !(line.starts_with('#') || line.trim().is_empty()) {
            break;
        }
    }
    options
}

/// A hostile scene name (newlines, `%`, `$()`, quotes, a `;`) reaches the farm's scripts
/// only as inert text: run with `sbatch` and `phenomena` stubbed and every command they
/// execute traced, the scripts run nothing but `sbatch` and `phenomena` (and the shell's
/// own `set`, `cd`, `echo` and assignments), the scene's path reaches `phenomena` whole,
/// and sbatch still sees every `#SBATCH` option.
#[test]
fn the_farm_scripts_run_only_sbatch_and_phenomena_whatever_the_names() {
    let dir = tempfile::tempdir().unwrap();
    let stubs = dir.path().join("stubs");
    std::fs::create_dir(&stubs).unwrap();
    let name = "evil\ntouch PWNED\n#SBATCH --wrap=x\n%j $(touch PWNED) `touch PWNED`; touch PWNED 'q\".toml";
    let scene = write(dir.path(), name, TINY_FLAME);
    let stub = |file: &str, body: &str| {
        let p = stubs.join(file);
        std::fs::write(&p, format!("#!/bin/bash\n{body}\n")).unwrap();
        let mut perm = std::fs::metadata(&p).unwrap().permissions();
        std::os::unix::fs::PermissionsExt::set_mode(&mut perm, 0o755);
        std::fs::set_permissions(&p, perm).unwrap();
        p
    };
    stub("sbatch", "printf 'sbatch %s\\n' \"$*\" >> \"$STUB_LOG\"; echo 42");
    // The fake phenomena logs its command and writes the scene path it was given.
    let fake = stub(
        "phenomena",
        "printf 'phenomena %s\\n' \"$1\" >> \"$STUB_LOG\"; printf '%s' \"$2\" > \"$STUB_LOG.$1\"",
    );
    ok(
        dir.path(),
        &["farm", "slurm", &scene, "--out", "out", "--chunk", "2", "--phenomena", &fake.to_string_lossy()],
    );
    let farm = dir.path().join("out/farm");
    let allowed =
        ["set -euo pipefail", "cd ", "sim=$(sbatch ", "render=$(sbatch ", "echo ", "i=", "a=", "b=", "exec "];
    let mut runs = Vec::new();
    for (script, task) in [("submit.sh", None), ("simulate.sbatch", None), ("render.sbatch", Some(1))] {
        let path = farm.join(script);
        let text = std::fs::read_to_string(&path).unwrap();
        for command in traced(&path, &stubs, task) {
            assert!(allowed.iter().any(|a| command.starts_with(a)), "{script} ran `{command}`:\n{text}");
            runs.push(command);
        }
        if script != "submit.sh" {
            let options = sbatch_options(&text);
            for want in ["--job-name=", "--cpus-per-task=", "--mem=", "--output="] {
                assert!(options.iter().any(|o| o.starts_with(want)), "{script}: {want} not read:\n{text}");
            }
            assert!(!options.iter().any(|o| o.starts_with("--wrap")), "{script}: {options:?}");
            if script == "render.sbatch" {
                assert!(options.iter().any(|o| o == "--array=0-1"), "{options:?}");
            }
        }
    }
    for at in [dir.path(), farm.as_path()] {
        assert!(!at.join("PWNED").exists(), "an injected command ran");
    }
    for command in ["simulate", "render"] {
        let given = std::fs::read_to_string(stubs.join(format!("calls.log.{command}"))).unwrap();
        assert_eq!(given, scene, "{command} was given another scene path");
    }
    let calls = std::fs::read_to_string(stubs.join("calls.log")).unwrap();
    assert_eq!(
        calls.lines().collect::<Vec<_>>(),
        [
            "sbatch --parsable simulate.sbatch",
            "sbatch --parsable --dependency=afterok:42 render.sbatch",
            "phenomena simulate",
            "phenomena render"
        ],
        "{runs:?}"
    );
}

/// What sbatch would misread is refused with the value and what is allowed: a
/// partition or output folder with a newline, `%` (a Slurm file name pattern) or `\`.
#[test]
fn farm_names_sbatch_would_misread_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    let e = fails(
        dir.path(),
        &["farm", "slurm", &scene, "--out", "o", "--chunk", "2", "--partition", "gpu\nrm -rf ~"],
    );
    assert!(e.contains("--partition") && e.contains("ASCII letters"), "{e}");
    for out in ["o%j", "o\nx", "o\\x"] {
        let e = fails(dir.path(), &["farm", "slurm", &scene, "--out", out, "--chunk", "2"]);
        assert!(e.contains("--out") && e.contains("Slurm's file name patterns"), "{out:?}: {e}");
    }
    assert!(std::fs::read_dir(dir.path()).unwrap().count() == 1, "nothing but the scene is written");
    ok(dir.path(), &["farm", "slurm", &scene, "--out", "o", "--chunk", "2", "--partition", "gpu,cpu_2"]);
}

/// A flipbook is one atlas of every frame and an afterglow carries light across
/// frames: neither can be split into independent chunks, and both are refused with
/// the reason before anything is written.
#[test]
fn farm_refuses_what_chunks_cannot_render() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY_FLAME);
    let e =
        fails(dir.path(), &["farm", "slurm", &scene, "--out", "o", "--chunk", "2", "--format", "flipbook"]);
    assert!(e.contains("flipbook is one atlas"), "{e}");
    let aurora = write(
        dir.path(),
        "glow.toml",
        "[scene]\nframes = 4\nwidth = 32\nheight = 18\n[aurora]\n[render.sky]\nafterglow = true\n",
    );
    let e = fails(dir.path(), &["farm", "slurm", &aurora, "--out", "o2", "--chunk", "2"]);
    assert!(e.contains("afterglow") && e.contains("one machine"), "{e}");
    assert!(!dir.path().join("o").exists() && !dir.path().join("o2").exists());
}
