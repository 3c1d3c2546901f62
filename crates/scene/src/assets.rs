//! Every file a scene reads (a snow mesh, its glTF buffers, a background image, and
//! anything added later) is opened here, through [`Assets`]. Phenomenon modules get
//! their bytes only from it, so the studio's sandbox covers every asset field by
//! construction: there is no second list of fields to keep in step.
//!
//! - [`Assets::Folder`] (`render`, `export`, `validate`): paths relative to the scene
//!   file's folder; glTF buffer URIs relative to the glTF file or `data:` URIs (what
//!   the glTF 2.0 specification allows, §3.9.2), absolute ones and other schemes
//!   refused; only regular files (no FIFO, device or folder); at most
//!   [`MAX_FILE_BYTES`] per file.
//! - [`Assets::Sandbox`] (the studio): only files uploaded to the session's folder, by
//!   plain name: absolute paths, folders, `..`, symlinks, FIFOs and devices are refused
//!   before anything is read; at most the upload cap per file.
//! - [`Assets::Memory`]: files given as bytes by name (a game's own asset pack, tests).
//!
//! Errors name the scene key and the path or URI as written, never the folder they
//! were looked for in (a studio page must not learn the server's folders).

use std::collections::BTreeMap;
use std::fmt;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

use base64::Engine;
use phenomena_core::image::Frame;

/// Largest file read from a folder (meshes, glTF buffers, images): 1 GiB.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// Largest side of an image asset, pixels.
pub const MAX_IMAGE_SIDE_PX: u32 = 16384;

/// Most pixels of an image asset (8192², about 0.8 GB once decoded to linear floats).
pub const MAX_IMAGE_PIXELS: u64 = 1 << 26;

/// Where a scene's files come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Assets {
    /// Files on disk, relative to `dir` (the scene file's folder).
    Folder {
        /// The scene file's folder.
        dir: PathBuf,
    },
    /// Only plain file names in `dir`, each at most `max_bytes`.
    Sandbox {
        /// The session's upload folder.
        dir: PathBuf,
        /// Largest file, bytes.
        max_bytes: u64,
    },
    /// Files held in memory, by the name a scene gives them (`/`-separated).
    Memory(BTreeMap<String, Vec<u8>>),
}

/// Why a file could not be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct AssetError {
    /// The scene key that names the file (`geometry.mesh`).
    pub key: String,
    /// The path as written in the scene, and for a referenced file (a glTF buffer) its
    /// URI as written in the referring file.
    pub written: String,
    /// The URI, when the problem is with a file the asset refers to.
    pub uri: Option<String>,
    /// What is wrong, in words.
    pub problem: String,
}

impl fmt::Display for AssetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} = {:?}: ", self.key, self.written)?;
        if let Some(uri) = &self.uri {
            write!(f, "its glTF buffer {uri:?}: ")?;
        }
        f.write_str(&self.problem)
    }
}

impl Assets {
    /// Files beside `scene_file`.
    pub fn beside(scene_file: &Path) -> Self {
        let dir = scene_file.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        Assets::Folder { dir: dir.to_path_buf() }
    }

    /// No files at all (every read is refused).
    pub fn none() -> Self {
        Assets::Memory(BTreeMap::new())
    }

    /// The most bytes one file (and all files one asset refers to, together) may hold.
    pub fn file_cap(&self) -> u64 {
        match self {
            Assets::Sandbox { max_bytes, .. } => *max_bytes,
            _ => MAX_FILE_BYTES,
        }
    }

    /// Read the file scene key `key` names by `path` (as written in the scene).
    pub fn read(&self, key: &str, path: &Path) -> Result<Vec<u8>, AssetError> {
        let error = |problem: String| AssetError {
            key: key.to_string(),
            written: path.display().to_string(),
            uri: None,
            problem,
        };
        match self {
            Assets::Folder { dir } => read_file(&dir.join(path), MAX_FILE_BYTES, false).map_err(error),
            Assets::Sandbox { dir, max_bytes } => {
                let name = plain_name(path).ok_or_else(|| {
                    error("in the studio a scene reads only uploaded files: upload it and use its plain name (no folders)".into())
                })?;
                read_file(&dir.join(name), *max_bytes, true).map_err(error)
            }
            Assets::Memory(files) => {
                let name = path.to_string_lossy().replace('\\', "/");
                files.get(&name).cloned().ok_or_else(|| error("no file of that name was given".into()))
            }
        }
    }

    /// Read a file that the asset at `key` (`from`, as written in the scene) refers to
    /// by `uri`, as glTF buffers are: a `data:` URI, or a relative reference resolved
    /// against `from`'s folder (percent-encoding decoded). Absolute paths and other
    /// schemes (`file:`, `http:`) are refused; in the sandbox only a plain name is.
    pub fn read_referenced(&self, key: &str, from: &Path, uri: &str) -> Result<Vec<u8>, AssetError> {
        let error = |problem: String| AssetError {
            key: key.to_string(),
            written: from.display().to_string(),
            uri: Some(uri.to_string()),
            problem,
        };
        let cap = self.file_cap();
        if let Some(data) = uri.strip_prefix("data:") {
            return decode_data_uri(data, cap).map_err(error);
        }
        let relative = relative_reference(uri).map_err(error)?;
        let wrapped = |e: AssetError| error(e.problem);
        match self {
            Assets::Folder { dir } => {
                let base = dir.join(from);
                let folder = base.parent().unwrap_or(Path::new("."));
                read_file(&folder.join(&relative), MAX_FILE_BYTES, false).map_err(error)
            }
            Assets::Sandbox { .. } => {
                if plain_name(&relative).is_none() {
                    return Err(error(
                        "in the studio a glTF reads only buffers uploaded beside it, by plain name (no folders, no ..)"
                            .into(),
                    ));
                }
                self.read(key, &relative).map_err(wrapped)
            }
            Assets::Memory(_) => {
                let joined = from.parent().map_or(relative.clone(), |p| p.join(&relative));
                self.read(key, &joined).map_err(wrapped)
            }
        }
    }

    /// Read and decode an image file (PNG) named by `key` into a linear frame (sRGB
    /// decoded); at most [`MAX_IMAGE_SIDE_PX`] per side and [`MAX_IMAGE_PIXELS`] in all,
    /// checked from the header before decoding.
    pub fn image(&self, key: &str, path: &Path) -> Result<Frame, AssetError> {
        let bytes = self.read(key, path)?;
        let error = |problem: String| AssetError {
            key: key.to_string(),
            written: path.display().to_string(),
            uri: None,
            problem,
        };
        let reader = || {
            image::ImageReader::new(std::io::Cursor::new(bytes.as_slice()))
                .with_guessed_format()
                .map_err(|e| error(format!("cannot read the image: {e}")))
        };
        // The size from the header first: a small file can hold a huge image.
        let (w, h) = reader()?.into_dimensions().map_err(|e| error(format!("cannot read the image: {e}")))?;
        if w > MAX_IMAGE_SIDE_PX || h > MAX_IMAGE_SIDE_PX || u64::from(w) * u64::from(h) > MAX_IMAGE_PIXELS {
            return Err(error(format!(
                "the image is {w}x{h}: at most {MAX_IMAGE_PIXELS} pixels and {MAX_IMAGE_SIDE_PX} per side"
            )));
        }
        let mut reader = reader()?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_IMAGE_SIDE_PX);
        limits.max_image_height = Some(MAX_IMAGE_SIDE_PX);
        reader.limits(limits);
        let img = reader.decode().map_err(|e| error(format!("cannot read the image: {e}")))?.to_rgb8();
        let (w, h) = (img.width() as usize, img.height() as usize);
        Frame::from_srgb8(w, h, img.as_raw()).ok_or_else(|| error("the image has no pixels".into()))
    }
}

/// The single file name of `path` when it is nothing else (no folder, no `..`, not
/// absolute, not empty).
fn plain_name(path: &Path) -> Option<&std::ffi::OsStr> {
    let mut parts = path.components();
    match (parts.next(), parts.next()) {
        (Some(Component::Normal(name)), None) => Some(name),
        _ => None,
    }
}

/// A glTF URI that is a relative reference, percent-decoded into a path; refused when
/// absolute or of another scheme.
fn relative_reference(uri: &str) -> Result<PathBuf, String> {
    let has_scheme = uri
        .split_once(':')
        .is_some_and(|(scheme, _)| !scheme.is_empty() && !scheme.contains(['/', '\\', '?', '#']));
    if has_scheme {
        return Err(
            "only relative paths and data: URIs are allowed in glTF buffer URIs (glTF 2.0 §3.9.2)".into()
        );
    }
    if uri.contains(['?', '#']) {
        return Err("a buffer URI with a query or fragment is not a file".into());
    }
    let decoded = percent_decode(uri).ok_or("the URI's percent-encoding is not valid UTF-8")?;
    if decoded.is_empty() {
        return Err("the URI is empty".into());
    }
    if decoded.starts_with(['/', '\\']) || Path::new(&decoded).is_absolute() {
        return Err("absolute paths are refused: glTF buffer URIs are relative to the glTF file".into());
    }
    if decoded.contains('\0') {
        return Err("the URI holds a NUL character".into());
    }
    Ok(PathBuf::from(decoded))
}

/// `%XX` sequences to bytes (RFC 3986 §2.1): exactly two hexadecimal digits each.
fn percent_decode_bytes(s: &str) -> Option<Vec<u8>> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let digit = |k: usize| bytes.get(k).and_then(|&b| char::from(b).to_digit(16));
            let (hi, lo) = (digit(i + 1)?, digit(i + 2)?);
            out.push((hi * 16 + lo) as u8);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    Some(out)
}

/// [`percent_decode_bytes`] read as UTF-8 (a path).
fn percent_decode(s: &str) -> Option<String> {
    String::from_utf8(percent_decode_bytes(s)?).ok()
}

/// The bytes of a `data:` URI's body (`[<mediatype>][;base64],<data>`, RFC 2397).
fn decode_data_uri(body: &str, cap: u64) -> Result<Vec<u8>, String> {
    let (head, data) = body.split_once(',').ok_or("a data: URI needs a comma before its data")?;
    // Base64 grows data by 4/3: check the size before decoding.
    if data.len() as u64 / 4 * 3 > cap {
        return Err(format!("the data: URI holds more than {cap} bytes"));
    }
    let bytes = if head.ends_with(";base64") {
        base64::engine::general_purpose::STANDARD
            .decode(data.trim_end())
            .map_err(|e| format!("the data: URI is not valid base64: {e}"))?
    } else {
        percent_decode_bytes(data).ok_or("the data: URI's percent-encoding is not valid")?
    };
    if bytes.len() as u64 > cap {
        return Err(format!("the data: URI holds more than {cap} bytes"));
    }
    Ok(bytes)
}

/// Read a regular file of at most `cap` bytes. The file is opened without blocking (a
/// FIFO would wait for a writer for ever) and, with `no_symlinks`, without following a
/// symlink; its type and size are checked on the opened handle, so what is read is
/// what was checked.
pub(crate) fn read_file(path: &Path, cap: u64, no_symlinks: bool) -> Result<Vec<u8>, String> {
    let (file, len) = open_regular(path, no_symlinks)?;
    if len > cap {
        return Err(format!("the file holds {len} bytes, more than the limit of {cap}"));
    }
    read_capped(file, len, cap)
}

/// Read the rest of `file` (`len` bytes by its metadata), refusing more than `cap`.
pub(crate) fn read_capped(file: impl Read, len: u64, cap: u64) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::with_capacity(len.min(cap) as usize);
    // `take` holds the cap even if the file grows while it is read.
    file.take(cap + 1).read_to_end(&mut bytes).map_err(|e| io_problem(&e))?;
    if bytes.len() as u64 > cap {
        return Err(format!("the file grew past the limit of {cap} bytes while it was read"));
    }
    Ok(bytes)
}

/// Open a regular file for reading without blocking (a FIFO would wait for a writer
/// for ever) and, with `no_symlinks`, without following a symlink; its type is checked
/// before opening and again on the opened handle, so what is read is what was
/// checked. Returns the file and its length.
pub(crate) fn open_regular(path: &Path, no_symlinks: bool) -> Result<(std::fs::File, u64), String> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        let mut flags = libc::O_NONBLOCK | libc::O_NOCTTY;
        if no_symlinks {
            flags |= libc::O_NOFOLLOW;
        }
        options.custom_flags(flags);
    }
    #[cfg(not(unix))]
    {
        // Without O_NONBLOCK, look before opening (the window is the caller's own).
        let meta = if no_symlinks { std::fs::symlink_metadata(path) } else { std::fs::metadata(path) };
        match meta {
            Ok(m) if m.is_file() => {}
            Ok(_) => return Err("not a regular file".into()),
            Err(e) => return Err(io_problem(&e)),
        }
    }
    // Look first, so a device is not even opened (opening some has effects); the type
    // is checked again on the opened handle below.
    #[cfg(unix)]
    {
        let meta = if no_symlinks { std::fs::symlink_metadata(path) } else { std::fs::metadata(path) };
        match meta {
            Ok(m) if m.is_dir() => return Err("a folder, not a file".into()),
            Ok(m) if m.file_type().is_symlink() => return Err("a symlink, which is refused here".into()),
            Ok(m) if !m.is_file() => return Err("not a regular file (a device, FIFO or socket)".into()),
            Ok(_) => {}
            Err(e) => return Err(io_problem(&e)),
        }
    }
    let file = options.open(path).map_err(|e| io_problem(&e))?;
    let meta = file.metadata().map_err(|e| io_problem(&e))?;
    if !meta.is_file() {
        return Err(if meta.is_dir() {
            "a folder, not a file".into()
        } else {
            "not a regular file (a device, FIFO or socket)".into()
        });
    }
    Ok((file, meta.len()))
}

/// An IO error in words that name no path.
fn io_problem(e: &std::io::Error) -> String {
    use std::io::ErrorKind;
    #[cfg(unix)]
    if e.raw_os_error() == Some(libc::ELOOP) {
        return "a symlink, which is refused here".into();
    }
    match e.kind() {
        ErrorKind::NotFound => "no such file".into(),
        ErrorKind::PermissionDenied => "permission denied".into(),
        ErrorKind::IsADirectory => "a folder, not a file".into(),
        _ => format!("cannot read it ({})", e.kind()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder() -> (tempfile::TempDir, Assets) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        std::fs::write(dir.path().join("sub/mesh.gltf"), b"{}").unwrap();
        std::fs::write(dir.path().join("sub/data 1.bin"), b"abc").unwrap();
        std::fs::write(dir.path().join("top.bin"), b"top").unwrap();
        let assets = Assets::Folder { dir: dir.path().to_path_buf() };
        (dir, assets)
    }

    #[test]
    fn folder_reads_relative_files_and_referenced_buffers() {
        let (_dir, a) = folder();
        assert_eq!(a.read("geometry.mesh", Path::new("sub/mesh.gltf")).unwrap(), b"{}");
        let from = Path::new("sub/mesh.gltf");
        assert_eq!(a.read_referenced("geometry.mesh", from, "data%201.bin").unwrap(), b"abc");
        // `..` is a relative reference the glTF specification allows.
        assert_eq!(a.read_referenced("geometry.mesh", from, "../top.bin").unwrap(), b"top");
        assert_eq!(
            a.read_referenced("k", from, "data:application/octet-stream;base64,AAEC").unwrap(),
            [0, 1, 2]
        );
    }

    #[test]
    fn absolute_and_foreign_uris_are_refused_without_reading() {
        let (_dir, a) = folder();
        let from = Path::new("sub/mesh.gltf");
        for uri in
            ["/etc/passwd", "file:///etc/passwd", "http://example.com/a.bin", "%2Fetc%2Fpasswd", "a.bin?x"]
        {
            let e = a.read_referenced("geometry.mesh", from, uri).unwrap_err();
            assert_eq!(e.uri.as_deref(), Some(uri));
            assert!(e.to_string().starts_with("geometry.mesh = \"sub/mesh.gltf\": its glTF buffer"), "{e}");
        }
        let e = a.read_referenced("geometry.mesh", from, "/etc/passwd").unwrap_err();
        assert!(e.problem.contains("absolute paths are refused"), "{e}");
    }

    #[test]
    fn only_regular_files_are_read() {
        let (dir, a) = folder();
        let e = a.read("k", Path::new("sub")).unwrap_err();
        assert_eq!(e.problem, "a folder, not a file");
        let e = a.read("k", Path::new("missing.obj")).unwrap_err();
        assert_eq!(e.to_string(), "k = \"missing.obj\": no such file");
        assert!(!e.to_string().contains(&*dir.path().to_string_lossy()), "the folder is not named");
        #[cfg(unix)]
        {
            let e = a.read("k", Path::new("/dev/zero")).unwrap_err();
            assert!(e.problem.contains("not a regular file"), "{e}");
            // A FIFO is refused at once, not waited on.
            let made = std::process::Command::new("mkfifo").arg(dir.path().join("fifo")).status();
            assert!(made.expect("mkfifo runs").success());
            let e = a.read("k", Path::new("fifo")).unwrap_err();
            assert!(e.problem.contains("not a regular file"), "{e}");
        }
    }

    #[test]
    fn the_sandbox_takes_plain_uploaded_names_only() {
        let (dir, _) = folder();
        let a = Assets::Sandbox { dir: dir.path().join("sub"), max_bytes: 2 };
        assert_eq!(a.read("k", Path::new("mesh.gltf")).unwrap(), b"{}");
        for bad in ["../top.bin", "/etc/passwd", "sub/mesh.gltf", "..", "."] {
            let e = a.read("k", Path::new(bad)).unwrap_err();
            assert!(e.problem.contains("plain name"), "{bad}: {e}");
        }
        let e = a.read("k", Path::new("data 1.bin")).unwrap_err();
        assert!(e.problem.contains("more than the limit of 2"), "{e}");
        let from = Path::new("mesh.gltf");
        for bad in ["../top.bin", "/etc/passwd", "sub%2Fx.bin", "..%2Ftop.bin"] {
            let e = a.read_referenced("geometry.mesh", from, bad).unwrap_err();
            assert!(!e.problem.is_empty(), "{bad}");
        }
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink("/etc/hostname", dir.path().join("sub/link.bin")).unwrap();
            let e = a.read("k", Path::new("link.bin")).unwrap_err();
            assert!(e.problem.contains("symlink"), "{e}");
            let e = a.read_referenced("k", from, "link.bin").unwrap_err();
            assert!(e.problem.contains("symlink"), "{e}");
        }
    }

    #[test]
    fn data_uris_are_decoded_within_the_cap() {
        assert_eq!(decode_data_uri(";base64,aGk=", 10).unwrap(), b"hi");
        assert_eq!(decode_data_uri("text/plain,a%20b", 10).unwrap(), b"a b");
        assert!(decode_data_uri(";base64,aGk=", 1).is_err());
        assert!(decode_data_uri("no comma", 10).is_err());
        // Binary data percent-encoded (RFC 2397 allows any octets); digits only.
        assert_eq!(decode_data_uri("application/octet-stream,%FF%00a", 10).unwrap(), [255, 0, b'a']);
        assert!(decode_data_uri(",%+F", 10).is_err());
        assert!(decode_data_uri(",%4", 10).is_err());
        assert!(decode_data_uri(";base64,!!!!", 10).is_err());
    }

    #[test]
    fn memory_assets_resolve_relative_to_the_referring_file() {
        let a = Assets::Memory(BTreeMap::from([
            ("yard/yard.gltf".to_string(), b"{}".to_vec()),
            ("yard/buf.bin".to_string(), b"xyz".to_vec()),
        ]));
        assert_eq!(a.read("k", Path::new("yard/yard.gltf")).unwrap(), b"{}");
        assert_eq!(a.read_referenced("k", Path::new("yard/yard.gltf"), "buf.bin").unwrap(), b"xyz");
        assert!(Assets::none().read("k", Path::new("x")).is_err());
    }
}
