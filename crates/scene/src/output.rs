//! Writing files: the atomic write every output shares, numbered frame files
//! ([`NumberedFiles`], what each per-frame format writes through), and checkpoints
//! (written every N frames, found and read back). Every output goes to a temporary
//! name in the same folder (unique to the process) and is renamed into place, so an
//! interrupted write never leaves a half-written file under the real name.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use phenomena_core::color::srgb_encode_u8_fast;
use phenomena_core::image::Frame;
use phenomena_core::tonemap::Exposure;

use crate::error::SinkError;
use crate::sink::{FrameSink, Output, State};

pub(crate) fn error(e: impl std::fmt::Display) -> SinkError {
    SinkError(e.to_string())
}

/// Temporary names written so far by this process (for uniqueness).
static TEMPS: AtomicU64 = AtomicU64::new(0);

/// The temporary name used while writing `path`: `.NAME.PID-N.tmp` beside it, unique
/// to this process and write.
fn temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let n = TEMPS.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.{}-{n}.tmp", std::process::id()))
}

/// Write `path` atomically with a closure that writes the temporary file it is given;
/// its error (the cause alone) is reported as `cannot write PATH: cause`, naming the
/// file that was to be written, not the temporary one.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), SinkError>,
) -> Result<(), SinkError> {
    let tmp = temp_path(path);
    let result = write(&tmp)
        .map_err(|e| SinkError(format!("cannot write {}: {}", path.display(), e.0)))
        .and_then(|()| {
            std::fs::rename(&tmp, path)
                .map_err(|e| SinkError(format!("cannot rename {} to {}: {e}", tmp.display(), path.display())))
        });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Remove the file at `path` if there is one (a stale output about to be replaced).
pub(crate) fn remove_if_there(path: &Path) {
    let _ = std::fs::remove_file(path);
}

/// Write bytes atomically.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<(), SinkError> {
    write_atomic(path, |tmp| {
        let mut f = std::fs::File::create(tmp).map_err(|e| error(format!("cannot create the file: {e}")))?;
        f.write_all(bytes).map_err(error)?;
        f.sync_all().ok();
        Ok(())
    })
}

/// Temporary files left in `dir` by writers that are no longer running (killed
/// mid-write): `.NAME.PID-N.tmp` whose process `PID` is gone. Removes them; returns
/// how many.
pub fn remove_stale_temps(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else { return 0 };
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = stale_temp_pid(&name) else { continue };
        if !process_alive(pid) && std::fs::remove_file(entry.path()).is_ok() {
            removed += 1;
        }
    }
    removed
}

/// The writer's process id in a temporary name `.NAME.PID-N.tmp`.
fn stale_temp_pid(name: &str) -> Option<u32> {
    let body = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (_, tag) = body.rsplit_once('.')?;
    let (pid, n) = tag.split_once('-')?;
    n.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// Whether process `pid` may be running: asked of `/proc` (Linux); where there is no
/// `/proc`, yes, so nothing is removed.
fn process_alive(pid: u32) -> bool {
    let proc = Path::new("/proc");
    pid == std::process::id() || !proc.is_dir() || proc.join(pid.to_string()).exists()
}

/// Tone map a linear frame to 8-bit sRGB bytes (row-major RGB triples).
pub fn to_srgb8(frame: &Frame, exposure: &Exposure) -> Vec<u8> {
    use rayon::prelude::*;
    // Each value maps on its own, so chunks in parallel give the same bytes.
    const CHUNK: usize = 1 << 14;
    let linear = frame.to_interleaved();
    let mut out = vec![0u8; linear.len()];
    out.par_chunks_mut(CHUNK).zip(linear.par_chunks(CHUNK)).for_each(|(o, l)| {
        let mut k = 0;
        exposure.apply_all(l, |v| {
            o[k] = srgb_encode_u8_fast(v);
            k += 1;
        });
    });
    out
}

/// Write 8-bit RGB as PNG, atomically.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), SinkError> {
    write_atomic(path, |tmp| {
        image::save_buffer_with_format(
            tmp,
            rgb,
            width,
            height,
            image::ColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .map_err(error)
    })
}

/// Create `dir` (and parents) if missing; a clear error if that fails or it is a file.
pub fn ensure_dir(dir: &Path) -> Result<(), SinkError> {
    if dir.exists() && !dir.is_dir() {
        return Err(error(format!("{} exists and is not a directory", dir.display())));
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| error(format!("cannot create the output directory {}: {e}", dir.display())))?;
    // Probe writability now rather than after minutes of simulation.
    let probe = temp_path(&dir.join("write-test"));
    std::fs::write(&probe, b"")
        .map_err(|e| error(format!("the output directory {} is not writable: {e}", dir.display())))?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}

/// A sink of files: what an output format opens for a run ([`crate::format`]).
pub trait Files: FrameSink + Send {
    /// Whether frame `index` is already written whole (what `--resume` keeps).
    fn finished(&self, index: u32) -> bool;
    /// Frames written by this run, and frames kept because they were finished.
    fn counts(&self) -> (u32, u32);
    /// Memory it needs at its peak beside the simulation, bytes, from the state before
    /// the first frame (a flipbook's atlas, a volume's grids); checked against the
    /// budget before the run starts, which also checks the format's options.
    fn memory_bytes(&self, _state: State<'_>) -> Result<u64, SinkError> {
        Ok(0)
    }
    /// Refuse frames that would take more than `max_bytes` (what the budget leaves).
    fn limit_memory(&mut self, _max_bytes: u64) {}
    /// One line on what was written into `dir`.
    fn summary(&self, dir: &Path) -> String {
        let (written, kept) = self.counts();
        format!(
            "wrote {written} frame(s){} to {}",
            if kept > 0 { format!(", kept {kept} finished frame(s)") } else { String::new() },
            dir.display()
        )
    }
}

/// What a format writes for one frame into its own numbered file.
pub trait PerFrame: Send {
    /// The files' extension (`png`).
    fn extension(&self) -> &'static str;
    /// Whether the frame's image is needed (data formats write from the state alone).
    fn needs_image(&self) -> bool;
    /// Write `out` to `path`, atomically.
    fn write(&mut self, path: &Path, out: &Output<'_>) -> Result<(), SinkError>;
    /// Whether the file at `path` is a finished frame.
    fn finished(&self, path: &Path) -> bool {
        path.is_file()
    }
    /// As [`Files::memory_bytes`].
    fn memory_bytes(&self, _state: State<'_>) -> Result<u64, SinkError> {
        Ok(0)
    }
    /// As [`Files::limit_memory`].
    fn limit_memory(&mut self, _max_bytes: u64) {}
}

/// Frames as numbered files, `DIR/frame_00000.EXT`, each written by a [`PerFrame`].
/// With `resume`, frames whose files are finished are kept (not written again) and
/// temporary files of writers that were killed are removed.
pub struct NumberedFiles<W> {
    dir: PathBuf,
    resume: bool,
    written: u32,
    kept: u32,
    writer: W,
}

impl<W: PerFrame> NumberedFiles<W> {
    /// Files into `dir` (created if missing).
    pub fn new(dir: &Path, resume: bool, writer: W) -> Result<Self, SinkError> {
        ensure_dir(dir)?;
        if resume {
            remove_stale_temps(dir);
        }
        Ok(Self { dir: dir.to_path_buf(), resume, written: 0, kept: 0, writer })
    }

    /// The file of frame `index`.
    pub fn path(&self, index: u32) -> PathBuf {
        self.dir.join(format!("frame_{index:05}.{}", self.writer.extension()))
    }
}

impl<W: PerFrame> FrameSink for NumberedFiles<W> {
    fn wants(&mut self, index: u32) -> bool {
        if self.resume && self.finished(index) {
            self.kept += 1;
            return false;
        }
        true
    }

    fn needs_image(&self) -> bool {
        self.writer.needs_image()
    }

    fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
        let path = self.path(out.index);
        self.writer.write(&path, out)?;
        self.written += 1;
        Ok(())
    }
}

impl<W: PerFrame> Files for NumberedFiles<W> {
    fn finished(&self, index: u32) -> bool {
        self.writer.finished(&self.path(index))
    }

    fn counts(&self) -> (u32, u32) {
        (self.written, self.kept)
    }

    fn memory_bytes(&self, state: State<'_>) -> Result<u64, SinkError> {
        self.writer.memory_bytes(state)
    }

    fn limit_memory(&mut self, max_bytes: u64) {
        self.writer.limit_memory(max_bytes)
    }
}

/// The manifest beside a volume file: `frame_00000.vdb.json` (each grid as OpenVDB will
/// report it, [`crate::phenomenon::encode_volume`]).
pub fn manifest_path(vdb: &Path) -> PathBuf {
    let mut name = vdb.file_name().unwrap_or_default().to_os_string();
    name.push(".json");
    vdb.with_file_name(name)
}

/// The file of the checkpoint from which frame `frames_done` is the next to simulate.
pub fn checkpoint_path(dir: &Path, frames_done: u32) -> PathBuf {
    dir.join(format!("checkpoint_{frames_done:05}.{CHECKPOINT_EXTENSION}"))
}

/// Checkpoint files' extension.
pub const CHECKPOINT_EXTENSION: &str = "ckpt";

/// The simulation's state every `every` frames as `DIR/checkpoint_NNNNN.ckpt` (NNNNN:
/// the frames simulated, i.e. the next frame to simulate), atomically; the frames need
/// not be rendered.
pub struct CheckpointSink {
    dir: PathBuf,
    every: u32,
    written: u32,
}

impl CheckpointSink {
    /// Checkpoints into `dir` (created if missing) after every `every` frames (at
    /// least 1).
    pub fn new(dir: &Path, every: u32) -> Result<Self, SinkError> {
        if every == 0 {
            return Err(error("checkpoints every 0 frames: give a whole number of frames from 1"));
        }
        ensure_dir(dir)?;
        remove_stale_temps(dir);
        Ok(Self { dir: dir.to_path_buf(), every, written: 0 })
    }

    /// Checkpoints written.
    pub fn written(&self) -> u32 {
        self.written
    }
}

impl FrameSink for CheckpointSink {
    fn wants(&mut self, index: u32) -> bool {
        (index + 1).is_multiple_of(self.every)
    }

    fn needs_image(&self) -> bool {
        false
    }

    fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
        let bytes = out.data.checkpoint()?;
        write_bytes_atomic(&checkpoint_path(&self.dir, out.index + 1), &bytes)?;
        self.written += 1;
        Ok(())
    }
}

/// The checkpoints in `dir`, by frames simulated (from their names; not opened),
/// oldest first. A missing folder has none.
pub fn list_checkpoints(dir: &Path) -> Vec<(u32, PathBuf)> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut found: Vec<(u32, PathBuf)> = entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let n = name.strip_prefix("checkpoint_")?.strip_suffix(&format!(".{CHECKPOINT_EXTENSION}"))?;
            Some((n.parse().ok()?, e.path()))
        })
        .collect();
    found.sort();
    found
}

/// Read a checkpoint file of at most `max_bytes` (what the memory budget leaves). Only
/// a regular file is opened (a FIFO or a device, also behind a symlink, is refused
/// without blocking or reading), and its header is read and checked first: a file that
/// is not a checkpoint, whose length is not the one its header gives, or that is larger
/// than `max_bytes` is refused before the rest of it is read.
pub fn read_checkpoint(path: &Path, max_bytes: u64) -> Result<Vec<u8>, SinkError> {
    use std::io::Read as _;
    let problem = |e: String| error(format!("cannot read it: {e}"));
    let (mut file, len) = crate::assets::open_regular(path, false).map_err(problem)?;
    let mut bytes = Vec::new();
    (&mut file)
        .take(crate::checkpoint::MAX_HEADER_BYTES as u64)
        .read_to_end(&mut bytes)
        .map_err(|e| problem(e.to_string()))?;
    let (_, _, needed) = crate::checkpoint::read_header(&bytes).map_err(|e| error(e.to_string()))?;
    if needed != len {
        let what = if needed > len { "truncated" } else { "followed by other data" };
        return Err(error(format!(
            "the checkpoint is {what}: its header gives {needed} bytes, the file holds {len}"
        )));
    }
    if len > max_bytes {
        return Err(error(format!(
            "the checkpoint holds {len} bytes, more than the memory budget leaves for reading it ({max_bytes} bytes): raise --max-memory-gib"
        )));
    }
    let rest = crate::assets::read_capped(file, len - bytes.len() as u64, needed - bytes.len() as u64)
        .map_err(problem)?;
    bytes.extend_from_slice(&rest);
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_writes_leave_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        let r = write_atomic(&path, |tmp| {
            std::fs::write(tmp, b"partial").unwrap();
            Err(SinkError("simulated failure".into()))
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        write_bytes_atomic(&path, b"ok").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"ok");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// A checkpoint is read header first: a file that is not one, is longer or shorter
    /// than its header says, or is larger than the budget leaves is refused having read
    /// at most the header's bytes; a FIFO is refused without blocking.
    #[test]
    fn checkpoints_are_refused_by_their_header_before_being_read() {
        let dir = tempfile::tempdir().unwrap();
        let header =
            crate::checkpoint::Header { phenomenon: "flame".into(), identity: 1, seed: 2, frames_done: 3 };
        let bytes = crate::checkpoint::encode(&header, &vec![7u32; 1000]).unwrap();
        let path = dir.path().join("checkpoint_00003.ckpt");
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(read_checkpoint(&path, bytes.len() as u64).unwrap(), bytes);
        let e = read_checkpoint(&path, bytes.len() as u64 - 1).unwrap_err().0;
        assert!(e.contains("more than the memory budget leaves"), "{e}");
        let mut longer = bytes.clone();
        longer.extend_from_slice(b"tail");
        std::fs::write(&path, &longer).unwrap();
        assert!(read_checkpoint(&path, u64::MAX).unwrap_err().0.contains("followed by other data"));
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert!(read_checkpoint(&path, u64::MAX).unwrap_err().0.contains("truncated"));
        // A sparse file far larger than the budget whose header is not a checkpoint's.
        let sparse = std::fs::File::create(&path).unwrap();
        sparse.set_len(1 << 40).unwrap();
        assert!(read_checkpoint(&path, 1 << 20).unwrap_err().0.contains("not a phenomena checkpoint"));
        #[cfg(unix)]
        {
            std::fs::remove_file(&path).unwrap();
            let made = std::process::Command::new("mkfifo").arg(&path).status();
            if made.is_ok_and(|s| s.success()) {
                assert!(read_checkpoint(&path, u64::MAX).unwrap_err().0.contains("not a regular file"));
            }
        }
    }

    #[test]
    fn temporary_names_are_unique_and_stale_ones_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let a = temp_path(&dir.path().join("frame_00001.exr"));
        let b = temp_path(&dir.path().join("frame_00001.exr"));
        assert_ne!(a, b);
        let name = a.file_name().unwrap().to_string_lossy().into_owned();
        assert_eq!(stale_temp_pid(&name), Some(std::process::id()));
        assert_eq!(stale_temp_pid(".frame_00001.exr.tmp"), None, "the old fixed name is not ours");
        // A temp of this (live) process stays; one of a process that cannot exist goes.
        std::fs::write(&a, b"x").unwrap();
        let dead = dir.path().join(".frame_00002.exr.4294967295-0.tmp");
        std::fs::write(&dead, b"x").unwrap();
        if Path::new("/proc").is_dir() {
            assert_eq!(remove_stale_temps(dir.path()), 1);
            assert!(a.exists() && !dead.exists());
        }
    }
}
