//! Checkpoints: a simulation's whole state at a frame, in a versioned, checksummed
//! binary file, so that a render can start at any frame without simulating the ones
//! before it. Encoding and decoding only; [`crate::output`] writes and finds
//! the files.
//!
//! # Format, version 2
//! All integers little-endian.
//!
//! | bytes | what |
//! | --- | --- |
//! | 8 | magic `PHNMCKPT` |
//! | 4 | format version (u32, [`FORMAT_VERSION`]) |
//! | 1 + n | the phenomenon's name: its length (u8), then ASCII |
//! | 8 | the scene's identity ([`identity`]: XXH3-64 of what the simulation is built from) |
//! | 8 | the seed |
//! | 8 | frames simulated (the next frame to simulate) |
//! | 8 | length of the state (u64) |
//! | length | the state: the phenomenon's `Simulation::State` as postcard 1.x |
//! | 8 | XXH3-64 of every byte before it |
//!
//! A checkpoint holds what the simulation cannot rebuild from the scene: particles,
//! fields, snow maps, frame counters. Every random number the phenomena draw is keyed
//! by (seed, purpose, frame or index), so no stream position needs saving.

use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;
use xxhash_rust::xxh3::xxh3_64;

/// The file's first bytes.
pub const MAGIC: &[u8; 8] = b"PHNMCKPT";
/// The format version this build writes and reads. Raised whenever a simulation's
/// state or what a frame's state means changes, so that an older checkpoint is refused
/// (and the render falls back to simulating) instead of resuming wrongly. 2: an aurora
/// frame ends with its renewal, so a version-1 state taken on a
/// renewal frame would skip that renewal.
pub const FORMAT_VERSION: u32 = 2;
/// Largest state a checkpoint may hold, bytes (a larger length is a corrupt file, not
/// an allocation to attempt).
pub const MAX_STATE_BYTES: u64 = 16 << 30;

/// What a checkpoint's header says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// The phenomenon (`flame`).
    pub phenomenon: String,
    /// The scene's identity ([`identity`]).
    pub identity: u64,
    /// The seed.
    pub seed: u64,
    /// Frames simulated: the checkpoint continues with this frame.
    pub frames_done: u64,
}

/// Why a checkpoint cannot be used.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CheckpointError {
    /// Not a checkpoint at all.
    #[error("not a phenomena checkpoint (it does not start with PHNMCKPT)")]
    NotACheckpoint,
    /// Written by another version of the format.
    #[error("checkpoint format version {found}; this build reads version {FORMAT_VERSION}")]
    Version {
        /// The version in the file.
        found: u32,
    },
    /// Shorter than its header says.
    #[error("the checkpoint is truncated ({len} bytes, {needed} needed)")]
    Truncated {
        /// Bytes there are.
        len: usize,
        /// Bytes the header promises.
        needed: u64,
    },
    /// The checksum does not match.
    #[error("the checkpoint is corrupt (its checksum does not match its contents)")]
    Checksum,
    /// A checkpoint of another scene, seed or phenomenon.
    #[error("the checkpoint belongs to another scene: {0}")]
    Mismatch(String),
    /// The state does not decode, or does not fit the simulation.
    #[error("the checkpoint's state cannot be used: {0}")]
    State(String),
}

/// The identity of what a simulation is built from: XXH3-64 of the phenomenon's name,
/// the simulation's part of the scene as canonical JSON (`simulation`: every table but
/// `[scene]` and `[render]`, which only say how frames are drawn and how many), and a
/// hash of the files it reads (the snow's mesh), if any. Changing the size, exposure,
/// camera or frame count of a scene keeps its checkpoints; changing its physics or seed
/// does not.
pub fn identity(phenomenon: &str, simulation: &Value, files: Option<u64>) -> u64 {
    let mut bytes = Vec::new();
    bytes.extend_from_slice(phenomenon.as_bytes());
    bytes.push(0);
    // serde_json writes object keys in the order of the phenomenon's structs (or sorted,
    // for maps), so the same scene always gives the same text.
    bytes.extend_from_slice(simulation.to_string().as_bytes());
    bytes.push(0);
    if let Some(f) = files {
        bytes.extend_from_slice(&f.to_le_bytes());
    }
    xxh3_64(&bytes)
}

/// A scene file's simulation tables: its JSON without `scene` and `render`.
pub fn simulation_tables(scene: &impl Serialize) -> Value {
    let mut json = serde_json::to_value(scene).unwrap_or(Value::Null);
    if let Value::Object(map) = &mut json {
        map.remove("scene");
        map.remove("render");
    }
    json
}

/// A hash of raw data, for [`identity`]'s `files`.
pub fn hash_bytes(bytes: &[u8]) -> u64 {
    xxh3_64(bytes)
}

/// Encode `state` under `header`.
pub fn encode<S: Serialize>(header: &Header, state: &S) -> Result<Vec<u8>, CheckpointError> {
    let payload = postcard::to_stdvec(state).map_err(|e| CheckpointError::State(e.to_string()))?;
    let name = header.phenomenon.as_bytes();
    let name_len =
        u8::try_from(name.len()).map_err(|_| CheckpointError::State("phenomenon name too long".into()))?;
    let mut out = Vec::with_capacity(payload.len() + 64 + name.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.push(name_len);
    out.extend_from_slice(name);
    for v in [header.identity, header.seed, header.frames_done, payload.len() as u64] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&payload);
    let sum = xxh3_64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    Ok(out)
}

/// Most bytes a header takes: magic, version, a name of up to 255 bytes, four u64.
pub const MAX_HEADER_BYTES: usize = 8 + 4 + 1 + 255 + 4 * 8;

/// The header at the start of a checkpoint, from its first bytes (`prefix`: the whole
/// file or at least its first [`MAX_HEADER_BYTES`]), checking its magic, version and
/// state length; returns the header, the header's length and the length the whole
/// file must have. Lets a reader refuse a file that is not a checkpoint, or is too
/// large, before reading the rest of it.
pub fn read_header(prefix: &[u8]) -> Result<(Header, usize, u64), CheckpointError> {
    let mut r = Reader { bytes: prefix, at: 0 };
    if r.take(8).ok() != Some(MAGIC.as_slice()) {
        return Err(CheckpointError::NotACheckpoint);
    }
    let found = r.u32()?;
    if found != FORMAT_VERSION {
        return Err(CheckpointError::Version { found });
    }
    let name_len = r.take(1)?[0] as usize;
    let phenomenon =
        std::str::from_utf8(r.take(name_len)?).map_err(|_| CheckpointError::Checksum)?.to_string();
    let (identity, seed, frames_done, len) = (r.u64()?, r.u64()?, r.u64()?, r.u64()?);
    let needed = (r.at as u64).saturating_add(len).saturating_add(8);
    if len > MAX_STATE_BYTES {
        return Err(CheckpointError::Truncated { len: prefix.len(), needed });
    }
    Ok((Header { phenomenon, identity, seed, frames_done }, r.at, needed))
}

/// Read a checkpoint's header, checking its magic, version, length and checksum;
/// returns the header and the state's bytes.
pub fn open(bytes: &[u8]) -> Result<(Header, &[u8]), CheckpointError> {
    let (header, at, needed) = read_header(bytes)?;
    if needed > bytes.len() as u64 {
        return Err(CheckpointError::Truncated { len: bytes.len(), needed });
    }
    let mut r = Reader { bytes, at };
    let payload = r.take((needed - at as u64 - 8) as usize)?;
    let body = r.at;
    let sum = r.u64()?;
    if xxh3_64(&bytes[..body]) != sum {
        return Err(CheckpointError::Checksum);
    }
    if r.at != bytes.len() {
        return Err(CheckpointError::Checksum);
    }
    Ok((header, payload))
}

/// Decode a checkpoint's state.
pub fn decode_state<S: DeserializeOwned>(payload: &[u8]) -> Result<S, CheckpointError> {
    postcard::from_bytes(payload).map_err(|e| CheckpointError::State(e.to_string()))
}

impl Header {
    /// `Ok` when this checkpoint was written for `expected`'s scene and seed.
    pub fn matches(&self, expected: &Header) -> Result<(), CheckpointError> {
        if self.phenomenon != expected.phenomenon {
            return Err(CheckpointError::Mismatch(format!(
                "it is a {} checkpoint, the scene is {}",
                self.phenomenon, expected.phenomenon
            )));
        }
        if self.seed != expected.seed {
            return Err(CheckpointError::Mismatch(format!(
                "it was made with seed {}, the scene has seed {}",
                self.seed, expected.seed
            )));
        }
        if self.identity != expected.identity {
            return Err(CheckpointError::Mismatch(format!(
                "its simulation settings (identity {:016x}) differ from the scene's ({:016x})",
                self.identity, expected.identity
            )));
        }
        Ok(())
    }
}

/// A cursor over a checkpoint's bytes.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], CheckpointError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(CheckpointError::Truncated { len: self.bytes.len(), needed: (self.at + n) as u64 });
        };
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32, CheckpointError> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self) -> Result<u64, CheckpointError> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Header {
        Header { phenomenon: "flame".into(), identity: 42, seed: 7, frames_done: 12 }
    }

    #[test]
    fn round_trip_and_every_damage_refused() {
        let state = (vec![1.5f32, -2.0, 3.25], 99u64, String::from("x"));
        let bytes = encode(&header(), &state).unwrap();
        let (h, payload) = open(&bytes).unwrap();
        assert_eq!(h, header());
        let back: (Vec<f32>, u64, String) = decode_state(payload).unwrap();
        assert_eq!(back, state);

        // Every truncation is refused, never a panic.
        for n in 0..bytes.len() {
            assert!(open(&bytes[..n]).is_err(), "truncated to {n} bytes was accepted");
        }
        // Every single flipped bit is caught (the magic, the version, the lengths or
        // the checksum).
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            assert!(open(&b).is_err(), "a flipped bit at byte {i} was accepted");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(open(&longer).err(), Some(CheckpointError::Checksum));
        assert_eq!(open(b"PNG\r\n\x1a\n").err(), Some(CheckpointError::NotACheckpoint));
        // Another version (an older build's, or a newer one's) is refused by name.
        for other in [FORMAT_VERSION - 1, FORMAT_VERSION + 1] {
            let mut b = bytes.clone();
            b[8..12].copy_from_slice(&other.to_le_bytes());
            assert_eq!(open(&b).err(), Some(CheckpointError::Version { found: other }));
        }
    }

    #[test]
    fn a_huge_length_is_refused_without_allocating() {
        let mut bytes = encode(&header(), &0u8).unwrap();
        // The length field sits after magic, version, name and three u64s.
        let at = 8 + 4 + 1 + 5 + 24;
        bytes[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(matches!(open(&bytes), Err(CheckpointError::Truncated { .. })));
    }

    #[test]
    fn headers_of_other_scenes_do_not_match() {
        let h = header();
        assert!(h.matches(&h).is_ok());
        for other in [
            Header { phenomenon: "aurora".into(), ..header() },
            Header { seed: 8, ..header() },
            Header { identity: 43, ..header() },
        ] {
            assert!(matches!(h.matches(&other), Err(CheckpointError::Mismatch(_))));
        }
        // The frame does not take part: any frame of the same scene matches.
        assert!(h.matches(&Header { frames_done: 0, ..header() }).is_ok());
    }

    #[test]
    fn identity_ignores_scene_and_render_tables() {
        let a = serde_json::json!({"scene": {"width": 64}, "flame": {"k": 1}, "render": {"x": 1}});
        let b = serde_json::json!({"scene": {"width": 128}, "flame": {"k": 1}, "render": {"x": 2}});
        let c = serde_json::json!({"scene": {"width": 64}, "flame": {"k": 2}, "render": {"x": 1}});
        let id = |v: &Value| identity("flame", &simulation_tables(v), None);
        assert_eq!(id(&a), id(&b));
        assert_ne!(id(&a), id(&c));
        assert_ne!(identity("flame", &simulation_tables(&a), Some(1)), id(&a));
    }
}
