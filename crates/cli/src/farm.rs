//! `phenomena farm slurm`: a render split over a Slurm cluster (issue 22). Two jobs: one
//! simulates the whole scene once, writing a checkpoint every K frames; then an array job
//! whose task i renders frames iK..(i+1)K from checkpoint iK, started only when the
//! simulation succeeded (`--dependency=afterok`). Each task's frames are byte-identical
//! to a render on one machine, and a failed task is rerun alone with
//! `sbatch --array=I render.sbatch`. We schedule nothing ourselves: Slurm does.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};
use phenomena_scene::output::{ensure_dir, write_bytes_atomic};

/// What a farm render is.
#[derive(Clone, Debug)]
pub(crate) struct FarmJob {
    pub(crate) scene: PathBuf,
    pub(crate) out: PathBuf,
    pub(crate) chunk: u32,
    pub(crate) partition: Option<String>,
    pub(crate) submit: bool,
    /// Arguments passed on to every `render` (size, seed, format, view).
    pub(crate) render_args: Vec<String>,
    /// Arguments passed on to `simulate` (the seed).
    pub(crate) simulate_args: Vec<String>,
    pub(crate) cpus_per_task: u16,
    /// The `phenomena` the jobs run (default: this one).
    pub(crate) binary: Option<PathBuf>,
}

/// Quote `s` for bash: as is when it holds only safe characters, in single quotes
/// otherwise, and as `$'...'` with escapes when it holds a control character (so no
/// line of a script is broken by a newline inside a name).
fn sh(s: &str) -> String {
    if !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric() || b"-_./=:,+@%".contains(&b)) {
        return s.to_string();
    }
    if !s.chars().any(char::is_control) {
        return format!("'{}'", s.replace('\'', r"'\''"));
    }
    let mut q = String::from("$'");
    for c in s.chars() {
        match c {
            '\\' | '\'' => {
                q.push('\\');
                q.push(c);
            }
            '\n' => q.push_str("\\n"),
            '\t' => q.push_str("\\t"),
            '\r' => q.push_str("\\r"),
            c if c.is_control() && (c as u32) < 0x80 => q.push_str(&format!("\\x{:02x}", c as u32)),
            c if c.is_control() => q.push_str(&format!("\\u{:04x}", c as u32)),
            c => q.push(c),
        }
    }
    q.push('\'');
    q
}

/// `s` for a comment line of a script: control characters (a newline would end the
/// comment and start a command) written as escapes, so the comment stays one line.
fn comment(s: &str) -> String {
    s.chars().map(|c| if c.is_control() { c.escape_default().collect() } else { c.to_string() }).collect()
}

/// A Slurm job name from a scene's file name: letters, digits, `.`, `_` and `-` kept,
/// anything else `_` (a job name is shown by `squeue` and passed through `#SBATCH`).
fn job_name(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || "._-".contains(c) { c } else { '_' }).collect()
}

/// A partition (or comma-separated list of partitions) as Slurm names them: refused,
/// naming the value and what is allowed, when it holds anything else (a newline would
/// end sbatch's reading of the `#SBATCH` lines and run the rest as a command).
fn check_partition(p: &str) -> Result<()> {
    if p.is_empty() || !p.chars().all(|c| c.is_ascii_alphanumeric() || "._-,".contains(c)) {
        bail!(
            "--partition {:?}: a partition name holds only ASCII letters, digits, `.`, `_` and `-` (several separated by `,`)",
            p
        );
    }
    Ok(())
}

/// The output folder as it reaches `#SBATCH --output`: no control character (a newline
/// ends the `#SBATCH` line), no `%` (Slurm expands it as a file name pattern) and no
/// `\` (which turns Slurm's patterns off, so every task would write one log).
fn check_out(out: &Path) -> Result<()> {
    let text = out.to_string_lossy();
    if let Some(c) = text.chars().find(|&c| c.is_control() || c == '%' || c == '\\') {
        bail!(
            "--out {:?}: the farm's log files are named through Slurm's file name patterns, where {:?} cannot be written; choose a folder whose path has no `%`, `\\` or control character",
            text,
            c
        );
    }
    Ok(())
}

fn abs(p: &Path) -> Result<PathBuf> {
    let p = if p.is_absolute() { p.to_path_buf() } else { std::env::current_dir()?.join(p) };
    Ok(p)
}

/// The `#SBATCH` lines every job shares.
fn header(job: &FarmJob, name: &str, mem_mib: u64) -> String {
    let mut h = String::from("#!/bin/bash\n");
    let _ = writeln!(h, "#SBATCH --job-name={}", job_name(name));
    let _ = writeln!(h, "#SBATCH --cpus-per-task={}", job.cpus_per_task);
    let _ = writeln!(h, "#SBATCH --mem={mem_mib}M");
    if let Some(p) = &job.partition {
        let _ = writeln!(h, "#SBATCH --partition={p}");
    }
    h
}

/// Write the farm's scripts under `OUT/farm/` (and with `--submit` submit them through
/// `sbatch`); returns a summary with what to run or watch.
pub(crate) fn slurm(job: &FarmJob) -> Result<String> {
    if job.chunk == 0 {
        bail!("--chunk 0: give the number of frames each task renders (1 or more)");
    }
    if let Some(p) = &job.partition {
        check_partition(p)?;
    }
    let out = abs(&job.out)?;
    check_out(&out)?;
    let scene_path = abs(&job.scene)?;
    let scene = phenomena_scene::load(&scene_path)?;
    // Refused now rather than on the farm: an invalid scene, a missing file, a scene
    // over the memory budget.
    let report = scene
        .check(&phenomena_scene::Assets::beside(&scene_path), &crate::render::limits())
        .map_err(|e| crate::render::located(&scene, e))?;
    if let Some(why) = scene.render_memory() {
        bail!(
            "{}: {why}, so a chunk cannot start from a checkpoint as the farm's tasks do: render it on one machine with `phenomena render`, or turn that off",
            job.scene.display()
        );
    }
    let total = scene.settings().frames;
    let tasks = total.div_ceil(job.chunk);
    let farm = out.join("farm");
    let logs = farm.join("logs");
    ensure_dir(&logs)?;
    let checkpoints = out.join("checkpoints");
    let frames = out.join("frames");
    let binary = match &job.binary {
        Some(b) => abs(b)?,
        None => std::env::current_exe().context("cannot find this phenomena binary")?,
    };
    // The estimate with room for the allocator and the frame writer; at least 256 MiB.
    let mem_mib = (report.estimate.memory_bytes / (1 << 20)) * 3 / 2 + 256;
    let stem = scene_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    // What comment lines and job names say of the scene; the paths the commands use are
    // quoted for the shell instead.
    let name = comment(&stem);
    let bin = sh(&binary.to_string_lossy());
    let scene_arg = sh(&scene_path.to_string_lossy());

    let mut simulate = header(job, &format!("phenomena-sim-{stem}"), mem_mib);
    let _ = writeln!(simulate, "#SBATCH --output={}", sh(&logs.join("simulate-%j.out").to_string_lossy()));
    let _ = writeln!(simulate, "# Simulate {name} once, a checkpoint every {} frames.", job.chunk);
    let _ = writeln!(simulate, "set -euo pipefail");
    let mut extra = job.simulate_args.iter().map(|a| format!(" {}", sh(a))).collect::<String>();
    let _ = writeln!(
        simulate,
        "exec {bin} simulate {scene_arg} --checkpoint-every {} --checkpoint-dir {} --threads \"${{SLURM_CPUS_PER_TASK:-1}}\"{extra}",
        job.chunk,
        sh(&checkpoints.to_string_lossy()),
    );

    extra = job.render_args.iter().map(|a| format!(" {}", sh(a))).collect();
    let mut render = header(job, &format!("phenomena-render-{stem}"), mem_mib);
    let _ = writeln!(render, "#SBATCH --array=0-{}", tasks - 1);
    let _ = writeln!(render, "#SBATCH --output={}", sh(&logs.join("render-%A_%a.out").to_string_lossy()));
    let _ = writeln!(
        render,
        "# Task i renders frames i*{k}..(i+1)*{k} of {name} from checkpoint i*{k}; rerun task i alone\n# with: sbatch --array=i {}",
        comment(&farm.join("render.sbatch").to_string_lossy()),
        k = job.chunk
    );
    let _ = writeln!(render, "set -euo pipefail");
    let _ =
        writeln!(render, "i=${{SLURM_ARRAY_TASK_ID:?this script is an array job: submit it with sbatch}}");
    let _ = writeln!(render, "a=$(( i * {} ))", job.chunk);
    let _ = writeln!(render, "b=$(( a + {} < {total} ? a + {} : {total} ))", job.chunk, job.chunk);
    let _ = writeln!(
        render,
        "exec {bin} render {scene_arg} --out {} --frames \"$a..$b\" --checkpoint-dir {} --threads \"${{SLURM_CPUS_PER_TASK:-1}}\"{extra}",
        sh(&frames.to_string_lossy()),
        sh(&checkpoints.to_string_lossy()),
    );

    let submit = format!(
        "#!/bin/bash\n# Submit the farm render of {name}: the simulation, then the render tasks after it.\nset -euo pipefail\ncd {}\nsim=$(sbatch --parsable simulate.sbatch)\nrender=$(sbatch --parsable --dependency=afterok:\"${{sim%%;*}}\" render.sbatch)\necho \"simulation job ${{sim%%;*}}, render array job ${{render%%;*}} ({tasks} tasks)\"\n",
        sh(&farm.to_string_lossy())
    );
    let scripts = [("simulate.sbatch", &simulate), ("render.sbatch", &render), ("submit.sh", &submit)];
    for (file, text) in scripts {
        let path = farm.join(file);
        write_bytes_atomic(&path, text.as_bytes())?;
        set_executable(&path)?;
    }
    let mut summary = format!(
        "{name}: {total} frames in {tasks} task(s) of {} frames; scripts in {}",
        job.chunk,
        farm.display()
    );
    if job.submit {
        let sim = sbatch(&farm, &["simulate.sbatch"])?;
        let dep = format!("--dependency=afterok:{sim}");
        let array = sbatch(&farm, &[&dep, "render.sbatch"])?;
        write_bytes_atomic(&farm.join("jobs.txt"), format!("simulate {sim}\nrender {array}\n").as_bytes())?;
        let _ = write!(
            summary,
            "\nsubmitted: simulation job {sim}, render array job {array}\nwatch: squeue -j {sim},{array}   finished: sacct -j {sim},{array} (sacct -c where accounting storage is off)   logs: {}\nrerun task I alone: sbatch --array=I {}",
            logs.display(),
            farm.join("render.sbatch").display()
        );
    } else {
        let _ = write!(summary, "\nsubmit with: {}", farm.join("submit.sh").display());
    }
    Ok(summary)
}

/// Run `sbatch --parsable ARGS` in `dir`; returns the job id.
fn sbatch(dir: &Path, args: &[&str]) -> Result<String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .current_dir(dir)
        .output()
        .context("cannot run sbatch (is Slurm installed and SLURM_CONF set?)")?;
    if !out.status.success() {
        bail!("sbatch {} failed: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim());
    }
    let text = String::from_utf8_lossy(&out.stdout);
    // `--parsable` prints `id` or `id;cluster`.
    let id = text.trim().split(';').next().unwrap_or_default().to_string();
    if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
        bail!("sbatch printed no job id: {text:?}");
    }
    Ok(id)
}

#[cfg(unix)]
fn set_executable(path: &Path) -> Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755))
        .with_context(|| format!("cannot make {} executable", path.display()))
}

#[cfg(not(unix))]
fn set_executable(_path: &Path) -> Result<()> {
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::sh;

    #[test]
    fn shell_quoting() {
        assert_eq!(sh("/a/b-c_d.toml"), "/a/b-c_d.toml");
        assert_eq!(sh("a b"), "'a b'");
        assert_eq!(sh("it's"), r"'it'\''s'");
        assert_eq!(sh("$(rm -rf /)"), "'$(rm -rf /)'");
        assert_eq!(sh(""), "''");
        assert_eq!(sh("a\nb'c\\"), r"$'a\nb\'c\\'");
    }
}
