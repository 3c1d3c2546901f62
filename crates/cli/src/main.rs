//! The `phenomena` command line: render scene files to images and export data.
#![allow(clippy::print_stdout, clippy::print_stderr)]

mod demo;
mod export;
mod farm;
mod render;
#[cfg(feature = "studio")]
mod studio;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::builder::PossibleValuesParser;
use clap::{Parser, Subcommand};
use phenomena_scene::atlas::{Alpha, FlipbookSettings};
use phenomena_scene::output::{ensure_dir, write_bytes_atomic};
use phenomena_scene::{Assets, Format, OutputOptions, VolumeOptions, registry};

use crate::export::TableFormat;
use crate::render::RenderJob;

/// Every view of every phenomenon (`--view`), from the registry.
fn view_names() -> PossibleValuesParser {
    let mut names: Vec<&'static str> =
        registry::PHENOMENA.iter().flat_map(|p| p.views().iter().map(|v| v.name)).collect();
    names.dedup();
    PossibleValuesParser::new(names)
}

/// Every phenomenon (`new`), from the registry.
fn phenomenon_names() -> PossibleValuesParser {
    PossibleValuesParser::new(registry::PHENOMENA.iter().map(|p| p.name()))
}

/// Every output format (`--format`), from the registry.
fn format_names() -> PossibleValuesParser {
    PossibleValuesParser::new(registry::FORMATS.iter().map(|f| f.name()))
}

/// The format named by `--format` (one of [`format_names`], so always found).
fn format_named(name: &str) -> anyhow::Result<Format> {
    Format::named(name).ok_or_else(|| anyhow::anyhow!("--format {name}: no such format"))
}

/// How a flipbook stores alpha.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum AlphaArg {
    /// Colour not multiplied by alpha.
    Straight,
    /// Colour multiplied by alpha.
    Premultiplied,
}

/// Options of the vdb and flipbook formats.
#[derive(clap::Args, Debug)]
struct OutputArgs {
    /// vdb: voxel size in metres (default: the flame's 0.01).
    #[arg(long, value_name = "M", conflicts_with = "voxel_km")]
    voxel_m: Option<f64>,
    /// vdb: voxel size in km (the aurora; default 1).
    #[arg(long, value_name = "KM")]
    voxel_km: Option<f64>,
    /// flipbook: cells and grid in powers of two (frames resampled to the cell size).
    #[arg(long)]
    pot: bool,
    /// flipbook: straight or premultiplied alpha.
    #[arg(long, value_enum, default_value_t = AlphaArg::Straight)]
    alpha: AlphaArg,
    /// flipbook: a seamless loop, the last K frames cross-faded into the first.
    #[arg(long = "loop", value_name = "K", default_value_t = 0)]
    loop_frames: u32,
    /// flipbook: cells cut to what the frames show (the bounds of every lit pixel over
    /// all frames, 2 px of margin); the descriptor says where they lie in the frame.
    #[arg(long)]
    crop: bool,
    /// flipbook: also `flipbook_motion.png`, each cell's motion vectors (where its light
    /// moves by the next frame), for shaders that blend frames along them (flame).
    #[arg(long)]
    motion: bool,
}

impl OutputArgs {
    /// The formats' options.
    fn options(&self) -> OutputOptions {
        OutputOptions {
            volume: VolumeOptions {
                voxel_m: self.voxel_m.or(self.voxel_km.map(|km| km * 1e3)),
                max_bytes: None,
            },
            flipbook: FlipbookSettings {
                power_of_two: self.pot,
                alpha: match self.alpha {
                    AlphaArg::Straight => Alpha::Straight,
                    AlphaArg::Premultiplied => Alpha::Premultiplied,
                },
                loop_frames: self.loop_frames,
                crop: self.crop,
                motion: self.motion,
            },
        }
    }
}

/// Simulate and render natural phenomena: flame, aurora, snow cover and sparkle.
#[derive(Parser, Debug)]
#[command(name = "phenomena", version, about, long_about = None)]
struct Cli {
    /// Log more (-v: info, with each scene's memory and work estimate; -vv: debug) to
    /// standard error.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Refuse a scene whose estimated memory is above this many GiB (default: three
    /// quarters of this machine's memory).
    #[arg(long, global = true, value_name = "GIB", value_parser = parse_gib)]
    max_memory_gib: Option<f64>,
    #[command(subcommand)]
    command: Command,
}

/// What `render` and `farm` may override of the scene.
#[derive(clap::Args, Debug, Clone, Copy)]
struct Overrides {
    /// Image width in pixels (overrides the scene).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    width: Option<u32>,
    /// Image height in pixels (overrides the scene).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    height: Option<u32>,
    /// Random seed (overrides the scene).
    #[arg(long)]
    seed: Option<u64>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Simulate a scene file and write its frames as DIR/frame_00000.png, ...
    Render(RenderArgs),
    /// Simulate a scene file without drawing it, writing checkpoints (the first stage of
    /// a farm render: `render --frames A..B` then starts at frame A from them).
    Simulate(SimulateArgs),
    /// Render on a farm: write (and submit) the jobs of a farm manager.
    Farm {
        #[command(subcommand)]
        manager: FarmManager,
    },
    /// Export data products.
    Export {
        #[command(subcommand)]
        what: ExportWhat,
    },
    /// Serve the studio: a local web page that draws aurora shapes, steers every
    /// phenomenon and shows it live (needs a build with `--features studio`).
    Studio(StudioArgs),
    /// Check a scene file and report every problem with file:line:column.
    Validate(ValidateArgs),
    /// Write a commented starter scene holding every default.
    New(NewArgs),
    /// Render a short showcase of every system into a folder.
    Demo(DemoArgs),
}

/// Farm managers.
#[derive(Subcommand, Debug)]
enum FarmManager {
    /// Slurm: OUT/farm/simulate.sbatch simulates the scene once, writing a checkpoint
    /// every CHUNK frames; OUT/farm/render.sbatch, an array job started after it
    /// succeeds, renders chunk i (frames i*CHUNK..) from its checkpoint into OUT/frames.
    Slurm(SlurmArgs),
}

/// Checkpoint options of `render`.
#[derive(clap::Args, Debug)]
struct CheckpointArgs {
    /// Write the simulation's whole state after every N frames as
    /// DIR/checkpoint_NNNNN.ckpt (NNNNN: the next frame to simulate).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    checkpoint_every: Option<u32>,
    /// Folder of the checkpoints, written and read (default: OUT/checkpoints). With
    /// --frames A..B or --resume the render starts from the newest usable checkpoint at
    /// or before the first frame it must make instead of frame 0.
    #[arg(long, value_name = "DIR")]
    checkpoint_dir: Option<PathBuf>,
}

/// Format of a data table.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum DataFormat {
    /// Comma-separated values with a header row.
    Csv,
}

/// Mesh file formats.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum MeshFormat {
    /// glTF 2.0 binary.
    Glb,
    /// Wavefront OBJ.
    Obj,
    /// Stanford PLY, binary little-endian.
    Ply,
}

/// Spectrum of precipitating electrons.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum SpectrumArg {
    /// All electrons at one energy.
    Mono,
    /// Maxwellian with the given characteristic energy.
    Maxwellian,
}

#[derive(Subcommand, Debug)]
enum ExportWhat {
    /// An aurora's particles after frame F: CSV `x,z,vx,vz` (km, km/s).
    Particles(AfterFrameArgs),
    /// An aurora's intermediate target shape at frame F: CSV `sheet,index,x,z,next`.
    Shape(AfterFrameArgs),
    /// The aurora's model atmosphere (NRLMSIS 2.1, 80-500 km at 1 km): CSV
    /// `altitude_km,n_o,n_n2,n_o2,temperature_k` (m⁻³, K).
    Atmosphere(AtmosphereArgs),
    /// The aurora's 1-D column model (physical mode): volume emission rate of each line,
    /// photons cm⁻³ s⁻¹, 80-500 km at 1 km: CSV
    /// `altitude_km,v_391_4,v_427_8,v_557_7,v_630_0,v_670_5`.
    AuroraProfile(AuroraProfileArgs),
    /// The snow of a snow scene as a mesh (closed solids per snow patch, with normals)
    /// after simulating it to `--time-h` hours (default: all the scene's frames).
    SnowMesh(SnowMeshArgs),
    /// A snow scene as its renderer draws it, as one GLB for another renderer or a DCC:
    /// the scene's objects, the snow (after `--time-h` hours), the camera and the sun,
    /// with the light settings in the scene's extras.
    SnowScene(SnowSceneArgs),
    /// The blackbody colour table (paper Fig 1): CIE 1931 xy and normalised linear sRGB.
    Blackbody(BlackbodyArgs),
}

#[derive(clap::Args, Debug)]
struct RenderArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Frames to write: A..B (B not included), A..=B, or N. Earlier frames are
    /// simulated but not written. Default: all of the scene's frames.
    #[arg(long, value_parser = render::parse_frame_range)]
    frames: Option<std::ops::Range<u32>>,
    #[command(flatten)]
    overrides: Overrides,
    /// Worker threads (default: one per core). Output is identical for any count.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// Output format: png (tone mapped, 8-bit sRGB), exr (linear float radiance), vdb
    /// (volumes), ply (particle caches) or flipbook (one atlas of every frame); which
    /// a phenomenon offers is checked before anything runs.
    #[arg(long, value_parser = format_names(), default_value = "png")]
    format: String,
    #[command(flatten)]
    output: OutputArgs,
    /// Skip frames whose files already exist (they are still simulated).
    #[arg(long)]
    resume: bool,
    /// Write one JSON object per frame (timings, particle counts) to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// What to draw: one of the scene's phenomenon's views (flame: flame, density;
    /// aurora: sky, plane; snow: scene, probability; sparkle: glints).
    #[arg(long, value_parser = view_names())]
    view: Option<String>,
    #[command(flatten)]
    checkpoints: CheckpointArgs,
}

#[derive(clap::Args, Debug)]
struct SimulateArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Frames to simulate: up to B (A..B starts from a checkpoint at or before A).
    /// Default: all of the scene's frames.
    #[arg(long, value_parser = render::parse_frame_range)]
    frames: Option<std::ops::Range<u32>>,
    /// Random seed (overrides the scene).
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: one per core). Output is identical for any count.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// Write a checkpoint after every N frames.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    checkpoint_every: u32,
    /// Folder of the checkpoints.
    #[arg(long, value_name = "DIR")]
    checkpoint_dir: PathBuf,
    /// Write one JSON object per frame (timings, particle counts) to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
struct StudioArgs {
    /// Address to listen on. Loopback by default: other machines cannot connect.
    #[arg(long, default_value = "127.0.0.1")]
    bind: std::net::IpAddr,
    /// Port (0 picks a free one; the address is printed).
    #[arg(long, default_value_t = 7878)]
    port: u16,
    /// Open the page in the desktop's browser.
    #[arg(long)]
    open: bool,
    /// Folder for "render final" outputs.
    #[arg(long, default_value = "studio-renders")]
    out: PathBuf,
    /// Most browser tabs served at once.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u16).range(1..=64))]
    max_sessions: u16,
    /// Another host name the page may be reached by (besides 127.0.0.1, localhost,
    /// ::1 and the --bind address); repeat for more. Requests naming any other
    /// host are refused (a defence against DNS rebinding).
    #[arg(long = "allow-host", value_name = "HOST")]
    allow_hosts: Vec<String>,
}

#[derive(clap::Args, Debug)]
struct ValidateArgs {
    /// The scene file (TOML).
    scene: PathBuf,
}

#[derive(clap::Args, Debug)]
struct NewArgs {
    /// The phenomenon.
    #[arg(value_parser = phenomenon_names())]
    phenomenon: String,
    /// Where to write it (default: `./PHENOMENON.toml`).
    path: Option<PathBuf>,
    /// Overwrite an existing file.
    #[arg(long)]
    force: bool,
}

#[derive(clap::Args, Debug)]
struct DemoArgs {
    /// Output directory.
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
}

#[derive(clap::Args, Debug)]
struct SlurmArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output folder: frames/, checkpoints/, farm/ (scripts and logs).
    #[arg(long)]
    out: PathBuf,
    /// Frames per render task.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    chunk: u32,
    /// Slurm partition (default: the cluster's default).
    #[arg(long)]
    partition: Option<String>,
    /// Submit the jobs with sbatch (otherwise run OUT/farm/submit.sh yourself).
    #[arg(long)]
    submit: bool,
    /// CPUs per job (each job uses that many threads).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=1024))]
    cpus_per_task: u16,
    /// The phenomena binary the jobs run, as the compute nodes see it (default: this one).
    #[arg(long, value_name = "PATH")]
    phenomena: Option<PathBuf>,
    #[command(flatten)]
    overrides: Overrides,
    /// Output format (one of render's).
    #[arg(long, value_parser = format_names(), default_value = "png")]
    format: String,
    /// What to draw (one of the phenomenon's views).
    #[arg(long, value_parser = view_names())]
    view: Option<String>,
}

/// An aurora export of the state after a frame.
#[derive(clap::Args, Debug)]
struct AfterFrameArgs {
    /// The aurora scene file.
    scene: PathBuf,
    /// The frame after which to export (0 = after the first step).
    #[arg(long)]
    frame: u32,
    /// Output CSV file.
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args, Debug)]
struct AtmosphereArgs {
    /// Only csv.
    #[arg(long, value_enum, default_value_t = DataFormat::Csv)]
    format: DataFormat,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args, Debug)]
struct AuroraProfileArgs {
    /// Mono-energetic energy or Maxwellian characteristic energy, keV (0.1-1000).
    #[arg(long)]
    energy_kev: f64,
    /// Electron spectrum.
    #[arg(long, value_enum, default_value_t = SpectrumArg::Maxwellian)]
    spectrum: SpectrumArg,
    /// Energy flux, erg cm⁻² s⁻¹.
    #[arg(long, default_value_t = 1.0)]
    flux_erg: f64,
    /// Only csv.
    #[arg(long, value_enum, default_value_t = DataFormat::Csv)]
    format: DataFormat,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
    /// Also write the red line's budget (electron density, O(¹D) production by
    /// source, the share that radiates, 630.0 nm) as CSV to this file.
    #[arg(long)]
    red_line: Option<PathBuf>,
    /// Also write the `paper` mode's expected emission by altitude (default
    /// `[render.sky.paper]`, production ratios from this column) as CSV to this
    /// file: `altitude_km,e_391_4,e_427_8,e_557_7,e_630_0,e_670_5`, emissions per
    /// falling electron per km, 1 km bins (centres).
    #[arg(long)]
    paper: Option<PathBuf>,
    /// Write the aurora's emission alone, without the night sky's own glow (the
    /// 630.0 nm of the night F region, IRI-90, which is there with no aurora at
    /// all): what the renderer draws on a curtain. By default the profile is what a
    /// photometer under the aurora sees, both together.
    #[arg(long)]
    aurora_only: bool,
    /// Use the air of other conditions: a directory with the three tables
    /// `atmosphere_msis21.csv` (O, N₂, O₂, T), `atmosphere_msis21_minor.csv` (N, NO)
    /// and `ionosphere_iri90.csv` (night O⁺), as `tools/gen_atmosphere.py --out DIR`
    /// and `tools/iri90/make_table.sh` write them. Default: the shipped tables
    /// (65° N 0° E, a winter midnight, F10.7 = 100, Ap = 10; `tests/data/air/tromso` has
    /// 69.6° N 19.0° E, F10.7 = 150, Ap = 15).
    #[arg(long, value_name = "DIR")]
    air: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
struct SnowMeshArgs {
    /// The snow scene file.
    scene: PathBuf,
    /// glb (glTF 2.0 binary), obj or ply (binary).
    #[arg(long, value_enum, default_value_t = MeshFormat::Glb)]
    format: MeshFormat,
    /// Simulated time, hours.
    #[arg(long)]
    time_h: Option<f64>,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args, Debug)]
struct SnowSceneArgs {
    /// The snow scene file.
    scene: PathBuf,
    /// Simulated time, hours.
    #[arg(long)]
    time_h: Option<f64>,
    /// Output file (GLB).
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args, Debug)]
struct BlackbodyArgs {
    /// Lowest temperature, K.
    #[arg(long, default_value_t = 1000.0)]
    min_k: f64,
    /// Highest temperature, K (included when on the step grid).
    #[arg(long, default_value_t = 10000.0)]
    max_k: f64,
    /// Temperature step, K.
    #[arg(long, default_value_t = 100.0)]
    step_k: f64,
    /// csv (temperature_k,x,y,r,g,b) or png (a 1-pixel-high strip).
    #[arg(long, value_enum, default_value_t = TableFormat::Csv)]
    format: TableFormat,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
}

fn run(cli: Cli) -> anyhow::Result<String> {
    // The studio shuts down on these signals itself.
    if !matches!(cli.command, Command::Studio(_)) {
        render::handle_signals();
    }
    match cli.command {
        Command::Render(a) => a.run(),
        Command::Simulate(a) => a.run(),
        Command::Farm { manager: FarmManager::Slurm(a) } => a.run(),
        Command::Export { what } => what.run(),
        Command::New(a) => a.run(),
        Command::Studio(a) => a.run(),
        Command::Demo(a) => demo::run(&a.out, a.threads.map(usize::from)),
        Command::Validate(a) => a.run(),
    }
}

impl RenderArgs {
    fn run(self) -> anyhow::Result<String> {
        let Overrides { width, height, seed } = self.overrides;
        let mut job = RenderJob::new(self.out, format_named(&self.format)?);
        job.job.frames = self.frames;
        job.job.options = self.output.options();
        job.job.resume = self.resume;
        job.job.checkpoint_every = self.checkpoints.checkpoint_every;
        job.job.checkpoint_dir = self.checkpoints.checkpoint_dir;
        let job = RenderJob {
            width,
            height,
            seed,
            threads: self.threads.map(usize::from),
            stats: self.stats,
            view: self.view,
            ..job
        };
        render::run(&self.scene, &job)
    }
}

impl SimulateArgs {
    fn run(self) -> anyhow::Result<String> {
        let mut job = RenderJob::new(self.checkpoint_dir.clone(), registry::FORMATS[0]);
        job.job.frames = self.frames;
        job.job.checkpoint_every = Some(self.checkpoint_every);
        job.job.checkpoint_dir = Some(self.checkpoint_dir);
        job.job.images = false;
        let job =
            RenderJob { seed: self.seed, threads: self.threads.map(usize::from), stats: self.stats, ..job };
        render::run(&self.scene, &job)
    }
}

impl SlurmArgs {
    fn run(self) -> anyhow::Result<String> {
        if !format_named(&self.format)?.resumable() {
            anyhow::bail!(
                "farm slurm --format {}: a flipbook is one atlas made of every frame, and the farm's tasks render their chunks apart; render png or exr frames on the farm, or the flipbook on one machine with `phenomena render --format flipbook`",
                self.format
            );
        }
        let Overrides { width, height, seed } = self.overrides;
        let mut render_args = Vec::new();
        let mut simulate_args = Vec::new();
        for (flag, value) in
            [("--width", width.map(|w| w.to_string())), ("--height", height.map(|h| h.to_string()))]
        {
            if let Some(v) = value {
                render_args.extend([flag.to_string(), v]);
            }
        }
        if let Some(s) = seed {
            for args in [&mut render_args, &mut simulate_args] {
                args.extend(["--seed".to_string(), s.to_string()]);
            }
        }
        render_args.extend(["--format".to_string(), self.format]);
        if let Some(v) = self.view {
            render_args.extend(["--view".to_string(), v]);
        }
        farm::slurm(&farm::FarmJob {
            scene: self.scene,
            out: self.out,
            chunk: self.chunk,
            partition: self.partition,
            submit: self.submit,
            render_args,
            simulate_args,
            cpus_per_task: self.cpus_per_task,
            binary: self.phenomena,
        })
    }
}

impl ExportWhat {
    fn run(self) -> anyhow::Result<String> {
        match self {
            ExportWhat::Blackbody(a) => export::blackbody(a.min_k, a.max_k, a.step_k, a.format, &a.out),
            ExportWhat::Atmosphere(a) => export::atmosphere(&a.out),
            ExportWhat::AuroraProfile(a) => a.run(),
            ExportWhat::SnowMesh(a) => a.run(),
            ExportWhat::SnowScene(a) => {
                export::scene_export(&a.scene, "snow-scene", "glb", snow_steps(a.time_h), &a.out)
            }
            ExportWhat::Particles(a) => {
                export::scene_export(&a.scene, "particles", "csv", |s| after_frame(s, a.frame), &a.out)
            }
            ExportWhat::Shape(a) => {
                export::scene_export(&a.scene, "shape", "csv", |s| after_frame(s, a.frame), &a.out)
            }
        }
    }
}

impl AuroraProfileArgs {
    fn run(self) -> anyhow::Result<String> {
        let spectrum = match self.spectrum {
            SpectrumArg::Mono => phenomena_aurora::deposition::Spectrum::Mono,
            SpectrumArg::Maxwellian => phenomena_aurora::deposition::Spectrum::Maxwellian,
        };
        let outputs = export::ProfileOutputs {
            out: &self.out,
            red_line: self.red_line.as_deref(),
            paper: self.paper.as_deref(),
            aurora_only: self.aurora_only,
        };
        export::aurora_profile(self.energy_kev, spectrum, self.flux_erg, self.air.as_deref(), &outputs)
    }
}

impl SnowMeshArgs {
    fn run(self) -> anyhow::Result<String> {
        let format = match self.format {
            MeshFormat::Glb => "glb",
            MeshFormat::Obj => "obj",
            MeshFormat::Ply => "ply",
        };
        export::scene_export(&self.scene, "snow-mesh", format, snow_steps(self.time_h), &self.out)
    }
}

/// The frames to simulate for `--time-h` hours (default: all the scene's frames), by the
/// scene's own frame time (one snow step per frame).
fn snow_steps(time_h: Option<f64>) -> impl Fn(&phenomena_scene::Scene) -> anyhow::Result<u32> {
    move |s: &phenomena_scene::Scene| {
        let dt_h = s.frame_time_s() / 3600.0;
        let time = time_h.unwrap_or(f64::from(s.settings().frames) * dt_h);
        if !(time.is_finite() && (0.0..=1e5).contains(&time)) {
            anyhow::bail!("--time-h {time} is out of range: expected hours in [0, 100000]");
        }
        Ok((time / dt_h).round() as u32)
    }
}

impl NewArgs {
    fn run(self) -> anyhow::Result<String> {
        let entry = registry::phenomenon(&self.phenomenon).ok_or_else(|| {
            anyhow::anyhow!("no phenomenon `{}`: use {}", self.phenomenon, registry::names())
        })?;
        let path = self.path.unwrap_or_else(|| PathBuf::from(format!("{}.toml", entry.name())));
        if path.exists() && !self.force {
            anyhow::bail!("{} already exists (use --force to overwrite)", path.display());
        }
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            ensure_dir(parent)?;
        }
        write_bytes_atomic(&path, entry.starter().as_bytes())?;
        // Each scene its own folder: starters of several phenomena do not overwrite each
        // other's frames.
        let stem = path.file_stem().map_or_else(|| entry.name().into(), |s| s.to_string_lossy());
        Ok(format!(
            "wrote {}; render it with: phenomena render {} --out out/{stem}",
            path.display(),
            path.display()
        ))
    }
}

impl StudioArgs {
    #[cfg(feature = "studio")]
    fn run(self) -> anyhow::Result<String> {
        studio::serve(studio::Options {
            bind: self.bind,
            port: self.port,
            open: self.open,
            out: self.out,
            max_sessions: usize::from(self.max_sessions),
            allow_hosts: self.allow_hosts,
        })
    }

    #[cfg(not(feature = "studio"))]
    fn run(self) -> anyhow::Result<String> {
        anyhow::bail!(
            "this phenomena was built without the studio: build it with `cargo build --release -p phenomena --features studio`"
        )
    }
}

impl ValidateArgs {
    fn run(self) -> anyhow::Result<String> {
        let s = phenomena_scene::load(&self.scene)?;
        // Everything `render` checks before its first frame, without building the
        // simulation: the files load, the simulation and renderer would accept the
        // scene, and its estimated memory is within the budget.
        let report =
            s.check(&Assets::beside(&self.scene), &render::limits()).map_err(|e| render::located(&s, e))?;
        for w in &report.warnings {
            eprintln!("warning: {w}");
        }
        for u in &report.estimate.unchecked {
            eprintln!("note: not checked before rendering: {u}");
        }
        render::log_estimate(&report.estimate);
        let st = s.settings();
        Ok(format!(
            "{}: ok ({} scene, {} frames at {}x{}, seed {}; about {} of memory)",
            self.scene.display(),
            s.phenomenon().name(),
            st.frames,
            st.width,
            st.height,
            st.seed,
            phenomena_scene::gib(report.estimate.memory_bytes)
        ))
    }
}

/// A memory budget in GiB: positive and finite.
fn parse_gib(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a positive number of GiB")),
    }
}

/// Steps to simulate for an export "after frame `frame`" (frame 0 is after the first
/// step), refusing frames past the scene's.
fn after_frame(scene: &phenomena_scene::Scene, frame: u32) -> anyhow::Result<u32> {
    let frames = scene.settings().frames;
    if frame >= frames {
        anyhow::bail!("--frame {frame} is past the scene's {frames} frames (0..{frames})");
    }
    Ok(frame + 1)
}

/// The instruction sets this build was compiled for (`.cargo/config.toml`: x86-64-v3)
/// that the running CPU does not report, so the binary can say so instead of dying on an
/// illegal instruction. `None` when all are there (always, off x86-64). Reads CPUID
/// itself: `is_x86_feature_detected!` answers from the compile-time features when they
/// are enabled, so it cannot tell.
#[inline(never)]
fn missing_cpu_features() -> Option<String> {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__cpuid, __cpuid_count};
        let leaf1 = __cpuid(1);
        let leaf7 = if __cpuid(0).eax >= 7 { __cpuid_count(7, 0).ebx } else { 0 };
        let ext1 = if __cpuid(0x8000_0000).eax >= 0x8000_0001 { __cpuid(0x8000_0001).ecx } else { 0 };
        let missing = missing_features(leaf1.ecx, leaf7, ext1);
        (!missing.is_empty()).then(|| missing.join(", "))
    }
    #[cfg(not(target_arch = "x86_64"))]
    None
}

/// The features this build needs that CPUID leaf 1 ECX, leaf 7 EBX and leaf 0x8000_0001
/// ECX do not show (bit numbers from Intel's SDM, vol. 2A, CPUID). AVX also needs the
/// operating system to save the wider registers, which OSXSAVE (leaf 1 ECX bit 27)
/// announces.
fn missing_features(leaf1_ecx: u32, leaf7_ebx: u32, ext1_ecx: u32) -> Vec<&'static str> {
    let bit = |word: u32, n: u32| word >> n & 1 == 1;
    let checks = [
        ("avx", cfg!(target_feature = "avx"), bit(leaf1_ecx, 28) && bit(leaf1_ecx, 27)),
        ("avx2", cfg!(target_feature = "avx2"), bit(leaf7_ebx, 5) && bit(leaf1_ecx, 27)),
        ("fma", cfg!(target_feature = "fma"), bit(leaf1_ecx, 12)),
        ("movbe", cfg!(target_feature = "movbe"), bit(leaf1_ecx, 22)),
        ("f16c", cfg!(target_feature = "f16c"), bit(leaf1_ecx, 29)),
        ("bmi1", cfg!(target_feature = "bmi1"), bit(leaf7_ebx, 3)),
        ("bmi2", cfg!(target_feature = "bmi2"), bit(leaf7_ebx, 8)),
        ("lzcnt", cfg!(target_feature = "lzcnt"), bit(ext1_ecx, 5)),
    ];
    checks.iter().filter(|(_, built_for, has)| *built_for && !has).map(|(name, ..)| *name).collect()
}

fn main() -> ExitCode {
    if let Some(missing) = missing_cpu_features() {
        eprintln!(
            "error: this build of phenomena needs CPU instructions this processor lacks ({missing}); \
             rebuild for it with: RUSTFLAGS=\"-C target-cpu=x86-64\" cargo build --release"
        );
        return ExitCode::FAILURE;
    }
    let cli = Cli::parse();
    render::set_budget(cli.max_memory_gib);
    let level = match cli.verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(level)),
        )
        .with_writer(std::io::stderr)
        .init();
    match run(cli) {
        Ok(summary) => {
            println!("{summary}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod cpu_tests {
    use super::missing_features;

    /// The machine that runs the tests has every instruction set the build targets.
    #[test]
    fn this_cpu_runs_this_build() {
        assert_eq!(super::missing_cpu_features(), None);
    }

    /// The decoding of the CPUID words: all bits set means nothing is missing; an old
    /// CPU (SSE only) misses every feature this build was compiled for; one cleared bit
    /// names exactly that feature.
    #[test]
    fn cpuid_bits_name_the_missing_features() {
        assert!(missing_features(u32::MAX, u32::MAX, u32::MAX).is_empty());
        let built_for: Vec<&str> = ["avx", "avx2", "fma", "movbe", "f16c", "bmi1", "bmi2", "lzcnt"]
            .into_iter()
            .filter(|f| match *f {
                "avx" => cfg!(target_feature = "avx"),
                "avx2" => cfg!(target_feature = "avx2"),
                "fma" => cfg!(target_feature = "fma"),
                "movbe" => cfg!(target_feature = "movbe"),
                "f16c" => cfg!(target_feature = "f16c"),
                "bmi1" => cfg!(target_feature = "bmi1"),
                "bmi2" => cfg!(target_feature = "bmi2"),
                _ => cfg!(target_feature = "lzcnt"),
            })
            .collect();
        assert_eq!(missing_features(0, 0, 0), built_for);
        if cfg!(target_feature = "avx2") {
            assert_eq!(missing_features(u32::MAX, !(1 << 5), u32::MAX), ["avx2"]);
            // Without OSXSAVE the operating system does not keep AVX registers.
            assert_eq!(missing_features(!(1 << 27), u32::MAX, u32::MAX), ["avx", "avx2"]);
        }
    }
}
