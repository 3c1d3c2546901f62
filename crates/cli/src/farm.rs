//! `phenomena farm slurm`: a render split over a Slurm cluster. Two jobs: one
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

/// Everything the three scripts are written from, checked and made absolute.
struct Layout {
    /// The scene's file name without extension, as the job names use it.
    stem: String,
    /// The same for comment lines (control characters escaped).
    name: String,
    /// `phenomena` and the scene, quoted for bash.
    bin: String,
    scene_arg: String,
    farm: PathBuf,
    logs: PathBuf,
    checkpoints: PathBuf,
    frames: PathBuf,
    total: u32,
    tasks: u32,
    mem_mib: u64,
}

/// Write the farm's scripts under `OUT/farm/` (and with `--submit` submit them through
/// `sbatch`); returns a summary with what to run or watch.
pub(crate) fn slurm(job: &FarmJob) -> Result<String> {
    let l = layout(job)?;
    ensure_dir(&l.logs)?;
    let scripts = [
        ("simulate.sbatch", simulate_script(job, &l)),
        ("render.sbatch", render_script(job, &l)),
        ("submit.sh", submit_script(&l)),
    ];
    for (file, text) in scripts {
        let path = l.farm.join(file);
        write_bytes_atomic(&path, text.as_bytes())?;
        set_executable(&path)?;
    }
    let mut summary = format!(
        "{}: {} frames in {} task(s) of {} frames; scripts in {}",
        l.name,
        l.total,
        l.tasks,
        job.chunk,
        l.farm.display()
    );
    if job.submit {
        let sim = sbatch(&l.farm, &["simulate.sbatch"])?;
        let dep = format!("--dependency=afterok:{sim}");
        let array = sbatch(&l.farm, &[&dep, "render.sbatch"])?;
        write_bytes_atomic(&l.farm.join("jobs.txt"), format!("simulate {sim}\nrender {array}\n").as_bytes())?;
        let _ = write!(
            summary,
            "\nsubmitted: simulation job {sim}, render array job {array}\nwatch: squeue -j {sim},{array}   finished: sacct -j {sim},{array} (sacct -c where accounting storage is off)   logs: {}\nrerun task I alone: sbatch --array=I {}",
            l.logs.display(),
            l.farm.join("render.sbatch").display()
        );
    } else {
        let _ = write!(summary, "\nsubmit with: {}", l.farm.join("submit.sh").display());
    }
    Ok(summary)
}

/// Check the job and the scene (refused now rather than on the farm: bad names, an
/// invalid scene, a missing file, a scene over the memory budget or one whose frames
/// cannot be rendered in chunks) and lay out its paths.
fn layout(job: &FarmJob) -> Result<Layout> {
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
    let report = scene
        .check(&phenomena_scene::Assets::beside(&scene_path), &crate::render::limits())
        .map_err(|e| crate::render::located(&scene, e))?;
    if let Some(why) = scene.render_memory() {
        bail!(
            "{}: {why}, so a chunk cannot start from a checkpoint as the farm's tasks do: render it on one machine with `phenomena render`, or turn that off",
            job.scene.display()
        );
    }
    let binary = match &job.binary {
        Some(b) => abs(b)?,
        None => std::env::current_exe().context("cannot find this phenomena binary")?,
    };
    let total = scene.settings().frames;
    let stem = scene_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let farm = out.join("farm");
    Ok(Layout {
        // What comment lines and job names say of the scene; the paths the commands use
        // are quoted for the shell instead.
        name: comment(&stem),
        stem,
        bin: sh(&binary.to_string_lossy()),
        scene_arg: sh(&scene_path.to_string_lossy()),
        logs: farm.join("logs"),
        farm,
        checkpoints: out.join("checkpoints"),
        frames: out.join("frames"),
        total,
        tasks: total.div_ceil(job.chunk),
        // The estimate with room for the allocator and the frame writer; at least 256 MiB.
        mem_mib: (report.estimate.memory_bytes / (1 << 20)) * 3 / 2 + 256,
    })
}

/// The simulation job: the whole scene once, a checkpoint every chunk.
fn simulate_script(job: &FarmJob, l: &Layout) -> String {
    let mut s = header(job, &format!("phenomena-sim-{}", l.stem), l.mem_mib);
    let _ = writeln!(s, "#SBATCH --output={}", sh(&l.logs.join("simulate-%j.out").to_string_lossy()));
    let _ = writeln!(s, "# Simulate {} once, a checkpoint every {} frames.", l.name, job.chunk);
    let _ = writeln!(s, "set -euo pipefail");
    let extra = job.simulate_args.iter().map(|a| format!(" {}", sh(a))).collect::<String>();
    let _ = writeln!(
        s,
        "exec {} simulate {} --checkpoint-every {} --checkpoint-dir {} --threads \"${{SLURM_CPUS_PER_TASK:-1}}\"{extra}",
        l.bin,
        l.scene_arg,
        job.chunk,
        sh(&l.checkpoints.to_string_lossy()),
    );
    s
}

/// The render array job: task i renders chunk i from its checkpoint.
fn render_script(job: &FarmJob, l: &Layout) -> String {
    let (k, total) = (job.chunk, l.total);
    let mut s = header(job, &format!("phenomena-render-{}", l.stem), l.mem_mib);
    let _ = writeln!(s, "#SBATCH --array=0-{}", l.tasks - 1);
    let _ = writeln!(s, "#SBATCH --output={}", sh(&l.logs.join("render-%A_%a.out").to_string_lossy()));
    let _ = writeln!(
        s,
        "# Task i renders frames i*{k}..(i+1)*{k} of {} from checkpoint i*{k}; rerun task i alone\n# with: sbatch --array=i {}",
        l.name,
        comment(&l.farm.join("render.sbatch").to_string_lossy()),
    );
    let _ = writeln!(s, "set -euo pipefail");
    let _ = writeln!(s, "i=${{SLURM_ARRAY_TASK_ID:?this script is an array job: submit it with sbatch}}");
    let _ = writeln!(s, "a=$(( i * {k} ))");
    let _ = writeln!(s, "b=$(( a + {k} < {total} ? a + {k} : {total} ))");
    let extra = job.render_args.iter().map(|a| format!(" {}", sh(a))).collect::<String>();
    let _ = writeln!(
        s,
        "exec {} render {} --out {} --frames \"$a..$b\" --checkpoint-dir {} --threads \"${{SLURM_CPUS_PER_TASK:-1}}\"{extra}",
        l.bin,
        l.scene_arg,
        sh(&l.frames.to_string_lossy()),
        sh(&l.checkpoints.to_string_lossy()),
    );
    s
}

/// The submission: the simulation, then the render tasks once it succeeded.
fn submit_script(l: &Layout) -> String {
    format!(
        "#!/bin/bash\n# Submit the farm render of {}: the simulation, then the render tasks after it.\nset -euo pipefail\ncd {}\nsim=$(sbatch --parsable simulate.sbatch)\nrender=$(sbatch --parsable --dependency=afterok:\"${{sim%%;*}}\" render.sbatch)\necho \"simulation job ${{sim%%;*}}, render array job ${{render%%;*}} ({} tasks)\"\n",
        l.name,
        sh(&l.farm.to_string_lossy()),
        l.tasks
    )
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
