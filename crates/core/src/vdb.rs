//! OpenVDB files (`.vdb`) written from sparse grids of 8³ leaves: float (`Tree_float_5_4_3`)
//! and three-float vector (`Tree_vec3s_5_4_3`) grids, encoded to bytes (no IO here).
//!
//! The layout is the one OpenVDB 10 writes and reads, file format version
//! [`FILE_VERSION`] 224, with the per-grid compression flag `COMPRESS_ACTIVE_MASK`: each
//! node stores only its active values. Every field follows the OpenVDB sources (Apache-2.0,
//! AcademySoftwareFoundation/openvdb), read for this module:
//!
//! - header, file metadata, grid count, grid descriptors and the three absolute stream
//!   positions per grid: `io/Archive.cc` (`writeHeader`, `write`, `writeGrid`) and
//!   `io/GridDescriptor.cc` (`writeHeader`, `writeStreamPos`, `addSuffix`);
//! - metadata maps (sorted by name, as `std::map` keeps them) and values:
//!   `MetaMap.cc` (`writeMeta`), `Metadata.h` (`writeSize`, `writeValue`), `Types.h`
//!   (`typeNameAsString`), `util/Name.h` (`writeString`); the standard grid entries of
//!   `Grid.cc` (`addStatsMetadata`, `META_*` names, `gridClassToString`);
//! - the transform: `math/Transform.cc` (`write`: the map's type name, then the map) and
//!   `math/Maps.h` (`ScaleTranslateMap::write`: translation, scale, voxel size, inverse
//!   scale, inverse scale squared, half the inverse scale, each three doubles);
//! - the tree: `tree/Tree.h` (`writeTopology`: buffer count 1), `tree/RootNode.h`
//!   (background, tile count, child count, then each child's origin and topology in the
//!   order of `std::map<Coord>`: x, then y, then z), `tree/InternalNode.h` (child mask,
//!   value mask, compressed values, children in offset order; `coordToOffset`),
//!   `tree/LeafNode.h` (`writeTopology`: the value mask; `writeBuffers`: the value mask
//!   again and the compressed values; `coordToOffset`: x·64 + y·8 + z within a leaf),
//!   `util/NodeMasks.h` (bit n is bit n % 64 of little-endian 64-bit word n / 64);
//! - value compression: `io/Compression.h` (`MaskCompress`, `writeCompressedValues`):
//!   one metadata byte per node, `NO_MASK_OR_INACTIVE_VALS` (0) here because every
//!   inactive value is the background 0, then the active values in offset order.
//!
//! A voxel is active exactly where its value is non-zero (any component, for vectors):
//! setting a voxel to 0 makes it inactive, and -0.0 reads back as +0.0. The background is
//! 0. Leaves with no active voxel are not written. The UUID in the header is derived from
//! a hash of the rest of the file, so the same grids give the same bytes; leaves are
//! encoded in parallel into fixed places, so the bytes do not depend on the thread count.
//!
//! ```
//! use phenomena_core::vdb::{encode, AnyGrid, Grid, GridClass, Metadata, Transform};
//! let transform = Transform::new(0.01, [0.0, 0.0, 0.0]).unwrap(); // 1 cm voxels
//! let mut density = Grid::<f32>::new("density", transform, GridClass::FogVolume);
//! density.add([1, 2, 3], 0.5);
//! density.add([1, 2, 3], 0.25);
//! density.insert_metadata("units", "kg/m^3").unwrap();
//! assert_eq!(density.get([1, 2, 3]), 0.75);
//! assert_eq!(density.active_voxel_count(), 1);
//! let bytes = encode(&[AnyGrid::from(&density)], &Metadata::new());
//! assert_eq!(&bytes[..8], &0x5644_4220_i64.to_le_bytes()); // OpenVDB's magic number
//! assert_eq!(bytes, encode(&[AnyGrid::from(&density)], &Metadata::new())); // deterministic
//! ```

use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};

/// The file format version written: OpenVDB 10's `OPENVDB_FILE_VERSION`
/// (`OPENVDB_FILE_VERSION_MULTIPASS_IO`, `version.h`).
pub const FILE_VERSION: u32 = 224;

/// The library version recorded in the header: the OpenVDB release whose format is
/// followed (10.0), as major and minor number.
pub const LIBRARY_VERSION: [u32; 2] = [10, 0];

/// Voxels in a leaf (8³), in OpenVDB's order: offset x·64 + y·8 + z ([`Grid::leaf_offset`]).
pub const LEAF_VOXELS: usize = 512;

/// OpenVDB's magic number (`OPENVDB_MAGIC`, written as a 64-bit integer).
const MAGIC: i64 = 0x5644_4220;
/// `io::COMPRESS_ACTIVE_MASK`: nodes store active values only.
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
/// `io::NO_MASK_OR_INACTIVE_VALS`: every inactive value is the (zero) background.
const NO_MASK_OR_INACTIVE_VALS: u8 = 0;
/// Bytes before the UUID: magic, file version, library major and minor, grid-offsets flag.
const UUID_AT: usize = 8 + 4 + 4 + 4 + 1;
/// The UUID's length: 32 hex digits and 4 hyphens.
const UUID_LEN: usize = 36;
/// Log2 of the edge of a leaf (8), an inner internal node (16 children) and an outer
/// internal node (32 children): the 5-4-3 tree.
const LEAF_LOG2: u32 = 3;
const INNER_LOG2: u32 = 4;
const OUTER_LOG2: u32 = 5;
/// Log2 of the voxel edge covered by an inner (128) and an outer internal node (4096).
const INNER_TOTAL: u32 = LEAF_LOG2 + INNER_LOG2;
const OUTER_TOTAL: u32 = INNER_TOTAL + OUTER_LOG2;
/// Mask bytes of a leaf, an inner and an outer internal node.
const LEAF_MASK_BYTES: usize = (1 << (3 * LEAF_LOG2)) / 8;
const INNER_MASK_BYTES: usize = (1 << (3 * INNER_LOG2)) / 8;
const OUTER_MASK_BYTES: usize = (1 << (3 * OUTER_LOG2)) / 8;
/// Grid metadata names the encoder writes itself (`Grid.cc`'s `META_*`), or that would
/// change how OpenVDB reads the grid (`is_saved_as_half_float`).
const RESERVED_NAMES: [&str; 9] = [
    "name",
    "class",
    "file_bbox_min",
    "file_bbox_max",
    "file_compression",
    "file_mem_bytes",
    "file_voxel_count",
    "file_delayed_load",
    "is_saved_as_half_float",
];

/// What can go wrong building a transform, metadata or a dense box.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum VdbError {
    /// The voxel size is not a positive finite number with a finite inverse square.
    #[error("voxel size {0} m must be a positive finite number (with a finite 1/size²)")]
    InvalidVoxelSize(f64),
    /// A translation component is not finite.
    #[error("translation {0:?} m must be finite")]
    InvalidTranslation([f64; 3]),
    /// Metadata needs a name (OpenVDB refuses an empty one when reading).
    #[error("a metadata name cannot be empty")]
    EmptyMetadataName,
    /// The name is one the encoder writes itself.
    #[error("metadata name {0:?} is written by the encoder itself")]
    ReservedMetadataName(String),
    /// OpenVDB stores string lengths as 32-bit integers.
    #[error("a string of {0} bytes is longer than OpenVDB's limit of 4 GiB")]
    StringTooLong(usize),
    /// A dense box's values do not match its dimensions.
    #[error("a dense box of {dims:?} voxels needs {expected} values, got {got}")]
    DenseLength {
        /// The box's dimensions.
        dims: [usize; 3],
        /// The number of values the box needs (0 if it overflows).
        expected: usize,
        /// The number of values given.
        got: usize,
    },
    /// A dense box reaches past the 32-bit index range.
    #[error("a dense box at {origin:?} of {dims:?} voxels leaves the 32-bit index range")]
    DenseOutOfRange {
        /// The box's lowest corner.
        origin: [i32; 3],
        /// The box's dimensions.
        dims: [usize; 3],
    },
}

/// A uniform index-to-world map: world = translation + voxel size · ijk, in metres.
///
/// OpenVDB voxel centres lie at integer index coordinates, so voxel `ijk` covers
/// `translation + voxel_size · (ijk ± 0.5)`. Written as OpenVDB's
/// `UniformScaleTranslateMap` (`math/Maps.h`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    voxel_size_m: f64,
    translation_m: [f64; 3],
}

impl Transform {
    /// A transform with cubic voxels of `voxel_size_m` metres whose voxel (0, 0, 0) is
    /// centred at `translation_m`.
    pub fn new(voxel_size_m: f64, translation_m: [f64; 3]) -> Result<Self, VdbError> {
        let inverse = 1.0 / voxel_size_m;
        if !(voxel_size_m > 0.0 && voxel_size_m.is_finite() && (inverse * inverse).is_finite()) {
            return Err(VdbError::InvalidVoxelSize(voxel_size_m));
        }
        if !translation_m.iter().all(|t| t.is_finite()) {
            return Err(VdbError::InvalidTranslation(translation_m));
        }
        Ok(Self { voxel_size_m, translation_m })
    }

    /// The voxel edge in metres.
    pub fn voxel_size_m(&self) -> f64 {
        self.voxel_size_m
    }

    /// The world position of the centre of voxel (0, 0, 0), in metres.
    pub fn translation_m(&self) -> [f64; 3] {
        self.translation_m
    }

    /// The world position (metres) of an index-space point, as OpenVDB's
    /// `ScaleTranslateMap::applyMap` computes it.
    pub fn index_to_world_m(&self, ijk: [f64; 3]) -> [f64; 3] {
        let t = self.translation_m;
        let s = self.voxel_size_m;
        [ijk[0] * s + t[0], ijk[1] * s + t[1], ijk[2] * s + t[2]]
    }

    /// The index-space point of a world position (metres), as OpenVDB's
    /// `ScaleTranslateMap::applyInverseMap`; the containing voxel is its rounding.
    pub fn world_to_index(&self, world_m: [f64; 3]) -> [f64; 3] {
        let t = self.translation_m;
        let inv = 1.0 / self.voxel_size_m;
        [(world_m[0] - t[0]) * inv, (world_m[1] - t[1]) * inv, (world_m[2] - t[2]) * inv]
    }

    /// `UniformScaleTranslateMap` as `Transform::write` and `ScaleTranslateMap::write`
    /// serialise it.
    fn write(&self, w: &mut Vec<u8>) {
        put_str(w, "UniformScaleTranslateMap");
        let s = self.voxel_size_m;
        let inv = 1.0 / s;
        put_f64s(w, &self.translation_m);
        put_f64s(w, &[s; 3]); // scale
        put_f64s(w, &[s.abs(); 3]); // voxel size
        put_f64s(w, &[inv; 3]); // 1 / scale
        put_f64s(w, &[inv * inv; 3]); // 1 / scale²
        put_f64s(w, &[inv / 2.0; 3]); // 1 / (2 scale)
    }
}

/// How a renderer should read a grid: OpenVDB's `GridClass`, written as the grid's
/// `class` metadata (`Grid.cc`, `gridClassToString`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridClass {
    /// A density-like field, zero outside (`"fog volume"`).
    FogVolume,
    /// Any other field (`"unknown"`).
    Unknown,
}

impl GridClass {
    /// The string OpenVDB stores for this class.
    pub fn as_str(self) -> &'static str {
        match self {
            GridClass::FogVolume => "fog volume",
            GridClass::Unknown => "unknown",
        }
    }
}

/// One metadata value, with OpenVDB's type name ([`MetaValue::type_name`]).
#[derive(Debug, Clone, PartialEq)]
pub enum MetaValue {
    /// `string`.
    String(String),
    /// `float`.
    Float(f32),
    /// `double`.
    Double(f64),
    /// `int32`.
    Int32(i32),
    /// `int64`.
    Int64(i64),
    /// `bool`.
    Bool(bool),
    /// `vec3i`.
    Vec3i([i32; 3]),
    /// `vec3s`.
    Vec3s([f32; 3]),
    /// `vec3d`.
    Vec3d([f64; 3]),
}

impl MetaValue {
    /// OpenVDB's name of the value's type (`Types.h`, `typeNameAsString`).
    pub fn type_name(&self) -> &'static str {
        match self {
            MetaValue::String(_) => "string",
            MetaValue::Float(_) => "float",
            MetaValue::Double(_) => "double",
            MetaValue::Int32(_) => "int32",
            MetaValue::Int64(_) => "int64",
            MetaValue::Bool(_) => "bool",
            MetaValue::Vec3i(_) => "vec3i",
            MetaValue::Vec3s(_) => "vec3s",
            MetaValue::Vec3d(_) => "vec3d",
        }
    }

    /// Name, type name, byte count and value, as `MetaMap::writeMeta` writes an entry.
    fn write(&self, name: &str, w: &mut Vec<u8>) {
        put_str(w, name);
        put_str(w, self.type_name());
        match self {
            MetaValue::String(s) => put_str(w, s),
            MetaValue::Float(v) => {
                put_u32(w, 4);
                w.extend_from_slice(&v.to_le_bytes());
            }
            MetaValue::Double(v) => {
                put_u32(w, 8);
                w.extend_from_slice(&v.to_le_bytes());
            }
            MetaValue::Int32(v) => {
                put_u32(w, 4);
                w.extend_from_slice(&v.to_le_bytes());
            }
            MetaValue::Int64(v) => {
                put_u32(w, 8);
                w.extend_from_slice(&v.to_le_bytes());
            }
            MetaValue::Bool(v) => {
                put_u32(w, 1);
                w.push(u8::from(*v));
            }
            MetaValue::Vec3i(v) => {
                put_u32(w, 12);
                v.iter().for_each(|c| w.extend_from_slice(&c.to_le_bytes()));
            }
            MetaValue::Vec3s(v) => {
                put_u32(w, 12);
                v.iter().for_each(|c| w.extend_from_slice(&c.to_le_bytes()));
            }
            MetaValue::Vec3d(v) => {
                put_u32(w, 24);
                put_f64s(w, v);
            }
        }
    }
}

impl From<&str> for MetaValue {
    fn from(v: &str) -> Self {
        MetaValue::String(v.to_owned())
    }
}
impl From<String> for MetaValue {
    fn from(v: String) -> Self {
        MetaValue::String(v)
    }
}
impl From<f32> for MetaValue {
    fn from(v: f32) -> Self {
        MetaValue::Float(v)
    }
}
impl From<f64> for MetaValue {
    fn from(v: f64) -> Self {
        MetaValue::Double(v)
    }
}
impl From<i32> for MetaValue {
    fn from(v: i32) -> Self {
        MetaValue::Int32(v)
    }
}
impl From<i64> for MetaValue {
    fn from(v: i64) -> Self {
        MetaValue::Int64(v)
    }
}
impl From<bool> for MetaValue {
    fn from(v: bool) -> Self {
        MetaValue::Bool(v)
    }
}

/// Named metadata, kept sorted by name as OpenVDB's `MetaMap` (a `std::map`) writes it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Metadata {
    entries: BTreeMap<String, MetaValue>,
}

impl Metadata {
    /// No entries.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds or replaces an entry. Names must not be empty; strings must fit OpenVDB's
    /// 32-bit lengths.
    pub fn insert(&mut self, name: impl Into<String>, value: impl Into<MetaValue>) -> Result<(), VdbError> {
        let name = name.into();
        let value = value.into();
        if name.is_empty() {
            return Err(VdbError::EmptyMetadataName);
        }
        check_len(&name)?;
        if let MetaValue::String(s) = &value {
            check_len(s)?;
        }
        self.entries.insert(name, value);
        Ok(())
    }

    /// The value of an entry.
    pub fn get(&self, name: &str) -> Option<&MetaValue> {
        self.entries.get(name)
    }

    /// The entries in name order.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &MetaValue)> {
        self.entries.iter().map(|(k, v)| (k.as_str(), v))
    }

    /// The number of entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// `MetaMap::writeMeta`: the count, then each entry in name order.
    fn write(&self, w: &mut Vec<u8>) {
        put_u32(w, self.entries.len() as u32);
        for (name, value) in &self.entries {
            value.write(name, w);
        }
    }
}

fn check_len(s: &str) -> Result<(), VdbError> {
    if u32::try_from(s.len()).is_err() {
        return Err(VdbError::StringTooLong(s.len()));
    }
    Ok(())
}

mod sealed {
    #[allow(unreachable_pub)] // a sealed supertrait: nameable nowhere outside this module
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for [f32; 3] {}
}

/// A voxel value type OpenVDB registers: `f32` (`Tree_float_5_4_3`) or `[f32; 3]`
/// (`Tree_vec3s_5_4_3`). Sealed: no other type has a registered tree.
pub trait Voxel: sealed::Sealed + Copy + PartialEq + Send + Sync + std::fmt::Debug + 'static {
    /// OpenVDB's tree type name (`Tree::treeType`).
    const TREE_TYPE: &'static str;
    /// The background (and inactive) value.
    const ZERO: Self;
    /// Bytes of one value in the file.
    const BYTES: usize;
    /// Whether the value is zero (every component), that is inactive.
    fn is_zero(self) -> bool;
    /// Adds `other` to the value (component-wise).
    fn accumulate(&mut self, other: Self);
    /// Writes the value's little-endian bytes into `out` (`BYTES` long).
    fn write_le(self, out: &mut [u8]);
    /// The value's components (one for a float).
    fn components(&self) -> &[f32];
    /// OpenVDB 10's in-memory sizes on x86-64 for `file_mem_bytes`: `sizeof` the tree,
    /// the root node, an internal node's table entry and a leaf node without its values.
    #[doc(hidden)]
    const MEM_SIZES: [u64; 4];
}

impl Voxel for f32 {
    const TREE_TYPE: &'static str = "Tree_float_5_4_3";
    const ZERO: Self = 0.0;
    const BYTES: usize = 4;
    const MEM_SIZES: [u64; 4] = [1232, 72, 8, 96];
    #[inline(always)]
    fn is_zero(self) -> bool {
        self == 0.0
    }
    #[inline(always)]
    fn accumulate(&mut self, other: Self) {
        *self += other;
    }
    #[inline(always)]
    fn write_le(self, out: &mut [u8]) {
        out[..4].copy_from_slice(&self.to_le_bytes());
    }
    fn components(&self) -> &[f32] {
        std::slice::from_ref(self)
    }
}

impl Voxel for [f32; 3] {
    const TREE_TYPE: &'static str = "Tree_vec3s_5_4_3";
    const ZERO: Self = [0.0; 3];
    const BYTES: usize = 12;
    const MEM_SIZES: [u64; 4] = [1240, 80, 16, 96];
    #[inline(always)]
    fn is_zero(self) -> bool {
        self[0] == 0.0 && self[1] == 0.0 && self[2] == 0.0
    }
    #[inline(always)]
    fn accumulate(&mut self, other: Self) {
        self[0] += other[0];
        self[1] += other[1];
        self[2] += other[2];
    }
    #[inline(always)]
    fn write_le(self, out: &mut [u8]) {
        out[0..4].copy_from_slice(&self[0].to_le_bytes());
        out[4..8].copy_from_slice(&self[1].to_le_bytes());
        out[8..12].copy_from_slice(&self[2].to_le_bytes());
    }
    fn components(&self) -> &[f32] {
        self
    }
}

/// A hasher for leaf origins (three `i32`): one multiply-rotate per word (FxHash's
/// step). Leaf lookups are on the voxelisation path; SipHash would dominate it.
#[derive(Default, Clone, Copy)]
struct OriginHasher(u64);

impl Hasher for OriginHasher {
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(4) {
            let mut word = [0u8; 4];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u32(u32::from_le_bytes(word));
        }
    }
    #[inline]
    fn write_u32(&mut self, n: u32) {
        self.0 = (self.0.rotate_left(5) ^ u64::from(n)).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    #[inline]
    fn write_i32(&mut self, n: i32) {
        self.write_u32(n as u32);
    }
    #[inline]
    fn write_usize(&mut self, n: usize) {
        self.write_u32(n as u32);
    }
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
}

/// A sparse grid of 8³ leaves, background 0, for one named field: OpenVDB's standard
/// 5-4-3 tree (root, 32³ internal nodes, 16³ internal nodes, 8³ leaves), built when
/// encoded. Leaves are created on first write and kept in creation order; the encoder
/// sorts them, so the bytes do not depend on the order voxels were written in.
#[derive(Clone)]
pub struct Grid<T: Voxel> {
    name: String,
    transform: Transform,
    class: GridClass,
    metadata: Metadata,
    origins: Vec<[i32; 3]>,
    leaves: Vec<[T; LEAF_VOXELS]>,
    index: HashMap<[i32; 3], u32, BuildHasherDefault<OriginHasher>>,
    /// Recently written leaves, direct-mapped by [`cache_slot`]: a splat touches up to
    /// eight neighbouring leaves, which fall in eight different slots, so its voxels
    /// find their leaf without hashing.
    recent: [([i32; 3], u32); CACHE_SLOTS],
}

/// Slots of a grid's leaf cache.
const CACHE_SLOTS: usize = 16;
/// An origin no leaf has (origins are multiples of 8): marks an empty cache slot.
const NO_LEAF: [i32; 3] = [1, 1, 1];

/// The cache slot of a leaf origin: neighbours in x, y, z and their combinations differ
/// by 1, 3, 5, 4, 6, 8, 9 slots, so a 2³ block of leaves never collides.
#[inline(always)]
fn cache_slot(origin: [i32; 3]) -> usize {
    let (x, y, z) = (origin[0] >> LEAF_LOG2, origin[1] >> LEAF_LOG2, origin[2] >> LEAF_LOG2);
    (x.wrapping_add(y.wrapping_mul(3)).wrapping_add(z.wrapping_mul(5)) as usize) % CACHE_SLOTS
}

impl<T: Voxel> std::fmt::Debug for Grid<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Grid")
            .field("name", &self.name)
            .field("type", &T::TREE_TYPE)
            .field("transform", &self.transform)
            .field("class", &self.class)
            .field("metadata", &self.metadata)
            .field("leaves", &self.leaves.len())
            .finish()
    }
}

impl<T: Voxel> Grid<T> {
    /// An empty grid. The name is the grid's `name` metadata and, made unique if two
    /// grids of a file share it, its descriptor name.
    ///
    /// # Panics
    /// If the name is 4 GiB or longer (OpenVDB stores 32-bit lengths).
    pub fn new(name: impl Into<String>, transform: Transform, class: GridClass) -> Self {
        let name = name.into();
        assert!(check_len(&name).is_ok(), "a grid name of {} bytes is too long for OpenVDB", name.len());
        Self {
            name,
            transform,
            class,
            metadata: Metadata::new(),
            origins: Vec::new(),
            leaves: Vec::new(),
            index: HashMap::default(),
            recent: [(NO_LEAF, 0); CACHE_SLOTS],
        }
    }

    /// The grid's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The index-to-world transform.
    pub fn transform(&self) -> &Transform {
        &self.transform
    }

    /// The grid class.
    pub fn class(&self) -> GridClass {
        self.class
    }

    /// The caller's metadata (the encoder adds the standard entries).
    pub fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    /// Adds or replaces a metadata entry, such as `units`. Refuses the names the encoder
    /// writes itself (`name`, `class`, `file_*`) and `is_saved_as_half_float`.
    pub fn insert_metadata(&mut self, name: &str, value: impl Into<MetaValue>) -> Result<(), VdbError> {
        if RESERVED_NAMES.contains(&name) {
            return Err(VdbError::ReservedMetadataName(name.to_owned()));
        }
        self.metadata.insert(name, value)
    }

    /// The origin (lowest corner) of the leaf holding voxel `ijk`.
    #[inline(always)]
    pub fn leaf_origin(ijk: [i32; 3]) -> [i32; 3] {
        const M: i32 = !((1 << LEAF_LOG2) - 1);
        [ijk[0] & M, ijk[1] & M, ijk[2] & M]
    }

    /// The offset of voxel `ijk` in its leaf's values: x·64 + y·8 + z of its position in
    /// the leaf (`LeafNode::coordToOffset`).
    #[inline(always)]
    pub fn leaf_offset(ijk: [i32; 3]) -> usize {
        (((ijk[0] & 7) << 6) | ((ijk[1] & 7) << 3) | (ijk[2] & 7)) as usize
    }

    /// The index of the leaf at `origin`, created (all zero) if absent.
    #[inline]
    fn leaf_index_mut(&mut self, origin: [i32; 3]) -> usize {
        let slot = cache_slot(origin);
        let (o, i) = self.recent[slot];
        if o == origin {
            return i as usize;
        }
        let next = self.leaves.len() as u32;
        let i = *self.index.entry(origin).or_insert(next);
        if i == next {
            self.origins.push(origin);
            self.leaves.push([T::ZERO; LEAF_VOXELS]);
        }
        self.recent[slot] = (origin, i);
        i as usize
    }

    /// Make room for `more` leaves beyond those there (one allocation instead of a
    /// vector that doubles while a frame fills it).
    pub fn reserve_leaves(&mut self, more: usize) {
        self.leaves.reserve(more);
        self.origins.reserve(more);
        self.index.reserve(more);
    }

    /// Add new leaves at `origins` (leaf origins, as [`Grid::leaf_origin`] gives, none of
    /// them in the grid yet, no two the same) and return their values, all zero, in that
    /// order, for the caller to fill (in parallel, say). `None`, and nothing added, when
    /// an origin is not a leaf origin, repeats or is already there.
    pub fn append_leaves(&mut self, origins: &[[i32; 3]]) -> Option<&mut [[T; LEAF_VOXELS]]> {
        let start = self.leaves.len();
        self.index.reserve(origins.len());
        for (k, &o) in origins.iter().enumerate() {
            if Self::leaf_origin(o) != o || self.index.insert(o, (start + k) as u32).is_some() {
                // Undo: the ones added so far, and the clashing one's earlier index.
                for &added in &origins[..k] {
                    self.index.remove(&added);
                }
                if Self::leaf_origin(o) == o
                    && let Some(at) = self.origins.iter().position(|&e| e == o)
                {
                    self.index.insert(o, at as u32);
                }
                self.recent = [(NO_LEAF, 0); CACHE_SLOTS];
                return None;
            }
        }
        self.origins.extend_from_slice(origins);
        self.leaves.resize(start + origins.len(), [T::ZERO; LEAF_VOXELS]);
        Some(&mut self.leaves[start..])
    }

    /// The values of the leaf holding voxel `ijk`, created (all zero) if absent, indexed
    /// by [`Grid::leaf_offset`]: the fast way to fill a whole leaf.
    pub fn leaf_mut(&mut self, ijk: [i32; 3]) -> &mut [T; LEAF_VOXELS] {
        let i = self.leaf_index_mut(Self::leaf_origin(ijk));
        &mut self.leaves[i]
    }

    /// The values of the leaf holding voxel `ijk`, if it exists.
    pub fn leaf(&self, ijk: [i32; 3]) -> Option<&[T; LEAF_VOXELS]> {
        self.index.get(&Self::leaf_origin(ijk)).map(|&i| &self.leaves[i as usize])
    }

    /// The value of voxel `ijk` (0 where nothing was written).
    pub fn get(&self, ijk: [i32; 3]) -> T {
        self.leaf(ijk).map_or(T::ZERO, |leaf| leaf[Self::leaf_offset(ijk)])
    }

    /// Sets voxel `ijk`; a non-zero value makes it active, zero inactive.
    #[inline]
    pub fn set(&mut self, ijk: [i32; 3], value: T) {
        if value.is_zero() && self.leaf(ijk).is_none() {
            return;
        }
        self.leaf_mut(ijk)[Self::leaf_offset(ijk)] = value;
    }

    /// Adds `value` to voxel `ijk` (for splatting).
    #[inline]
    pub fn add(&mut self, ijk: [i32; 3], value: T) {
        self.leaf_mut(ijk)[Self::leaf_offset(ijk)].accumulate(value);
    }

    /// Adds a dense box of values: `values[(x · dims[1] + y) · dims[2] + z]` goes to voxel
    /// `origin + (x, y, z)` (z fastest, as OpenVDB's `tools::Dense` with `LayoutZYX`).
    /// One leaf lookup per leaf the box touches.
    pub fn add_dense(&mut self, origin: [i32; 3], dims: [usize; 3], values: &[T]) -> Result<(), VdbError> {
        let expected = dims[0].checked_mul(dims[1]).and_then(|n| n.checked_mul(dims[2]));
        if expected != Some(values.len()) {
            return Err(VdbError::DenseLength { dims, expected: expected.unwrap_or(0), got: values.len() });
        }
        if values.is_empty() {
            return Ok(());
        }
        let mut hi = [0i32; 3]; // inclusive upper corner
        for a in 0..3 {
            let top = i64::from(origin[a]) + dims[a] as i64 - 1;
            hi[a] = i32::try_from(top).map_err(|_| VdbError::DenseOutOfRange { origin, dims })?;
        }
        let lo_leaf = Self::leaf_origin(origin);
        let hi_leaf = Self::leaf_origin(hi);
        let mut lx = lo_leaf[0];
        loop {
            let mut ly = lo_leaf[1];
            loop {
                let mut lz = lo_leaf[2];
                loop {
                    self.add_dense_leaf([lx, ly, lz], origin, hi, dims, values);
                    if lz == hi_leaf[2] {
                        break;
                    }
                    lz += 8;
                }
                if ly == hi_leaf[1] {
                    break;
                }
                ly += 8;
            }
            if lx == hi_leaf[0] {
                break;
            }
            lx += 8;
        }
        Ok(())
    }

    /// The part of a dense box in the leaf at `leaf`.
    fn add_dense_leaf(
        &mut self,
        leaf: [i32; 3],
        origin: [i32; 3],
        hi: [i32; 3],
        dims: [usize; 3],
        values: &[T],
    ) {
        let lo = [0, 1, 2].map(|a| leaf[a].max(origin[a]));
        let top = [0, 1, 2].map(|a| (leaf[a] + 7).min(hi[a]));
        let i = self.leaf_index_mut(leaf);
        let dst = &mut self.leaves[i];
        let nz = (top[2] - lo[2] + 1) as usize;
        for x in lo[0]..=top[0] {
            for y in lo[1]..=top[1] {
                let src0 = (((x - origin[0]) as usize * dims[1]) + (y - origin[1]) as usize) * dims[2]
                    + (lo[2] - origin[2]) as usize;
                let dst0 = Self::leaf_offset([x, y, lo[2]]);
                for (d, s) in dst[dst0..dst0 + nz].iter_mut().zip(&values[src0..src0 + nz]) {
                    d.accumulate(*s);
                }
            }
        }
    }

    /// The number of active (non-zero) voxels. Scans every stored leaf.
    pub fn active_voxel_count(&self) -> u64 {
        self.leaves.iter().map(|leaf| leaf.iter().filter(|v| !v.is_zero()).count() as u64).sum()
    }

    /// The number of leaves stored (including any whose voxels are all zero again).
    pub fn leaf_count(&self) -> usize {
        self.leaves.len()
    }

    /// Every stored leaf: its origin and values, in creation order.
    pub fn leaves(&self) -> impl Iterator<Item = ([i32; 3], &[T; LEAF_VOXELS])> {
        self.origins.iter().copied().zip(self.leaves.iter())
    }

    /// What OpenVDB reports of the grid once read: active voxels, their smallest and
    /// largest value (lexicographic for vectors, as `Grid::evalMinMax` compares) and the
    /// bounding box of the active voxels (`None` when there are none).
    pub fn summary(&self) -> Summary {
        let mut s = Summary { active_voxels: 0, min: Vec::new(), max: Vec::new(), bbox: None };
        for (origin, leaf) in self.origins.iter().zip(&self.leaves) {
            for (k, v) in leaf.iter().enumerate().filter(|(_, v)| !v.is_zero()) {
                let ijk = [
                    origin[0] + (k >> 6) as i32,
                    origin[1] + ((k >> 3) & 7) as i32,
                    origin[2] + (k & 7) as i32,
                ];
                let c = v.components();
                if s.active_voxels == 0 || lexicographic_less(c, &s.min) {
                    s.min = c.to_vec();
                }
                if s.active_voxels == 0 || lexicographic_less(&s.max, c) {
                    s.max = c.to_vec();
                }
                let (lo, hi) = s.bbox.get_or_insert((ijk, ijk));
                for a in 0..3 {
                    lo[a] = lo[a].min(ijk[a]);
                    hi[a] = hi[a].max(ijk[a]);
                }
                s.active_voxels += 1;
            }
        }
        s
    }

    /// Removes every voxel, keeping the allocations (for the next frame).
    pub fn clear(&mut self) {
        self.origins.clear();
        self.leaves.clear();
        self.index.clear();
        self.recent = [(NO_LEAF, 0); CACHE_SLOTS];
    }
}

/// A grid as OpenVDB will report it ([`Grid::summary`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Active voxels.
    pub active_voxels: u64,
    /// Smallest active value, by component (empty when there is none).
    pub min: Vec<f32>,
    /// Largest active value.
    pub max: Vec<f32>,
    /// Smallest and largest index of the active voxels.
    pub bbox: Option<([i32; 3], [i32; 3])>,
}

/// `a < b` comparing component by component, first difference deciding.
fn lexicographic_less(a: &[f32], b: &[f32]) -> bool {
    for (x, y) in a.iter().zip(b) {
        if x < y {
            return true;
        }
        if x > y {
            return false;
        }
    }
    false
}

/// A grid of either value type, for [`encode`] (a closed set, so an enum).
#[derive(Debug, Clone, Copy)]
pub enum AnyGrid<'a> {
    /// A float grid.
    Float(&'a Grid<f32>),
    /// A three-float vector grid.
    Vec3(&'a Grid<[f32; 3]>),
}

impl<'a> From<&'a Grid<f32>> for AnyGrid<'a> {
    fn from(g: &'a Grid<f32>) -> Self {
        AnyGrid::Float(g)
    }
}

impl<'a> From<&'a Grid<[f32; 3]>> for AnyGrid<'a> {
    fn from(g: &'a Grid<[f32; 3]>) -> Self {
        AnyGrid::Vec3(g)
    }
}

impl AnyGrid<'_> {
    /// The grid's name.
    pub fn name(&self) -> &str {
        match self {
            AnyGrid::Float(g) => g.name(),
            AnyGrid::Vec3(g) => g.name(),
        }
    }

    /// OpenVDB's value type name (`float`, `vec3s`: `valueTypeName` once read).
    pub fn value_type(&self) -> &'static str {
        match self {
            AnyGrid::Float(_) => "float",
            AnyGrid::Vec3(_) => "vec3s",
        }
    }

    /// The grid's transform.
    pub fn transform(&self) -> &Transform {
        match self {
            AnyGrid::Float(g) => g.transform(),
            AnyGrid::Vec3(g) => g.transform(),
        }
    }

    /// The grid's class.
    pub fn class(&self) -> GridClass {
        match self {
            AnyGrid::Float(g) => g.class(),
            AnyGrid::Vec3(g) => g.class(),
        }
    }

    /// [`Grid::summary`].
    pub fn summary(&self) -> Summary {
        match self {
            AnyGrid::Float(g) => g.summary(),
            AnyGrid::Vec3(g) => g.summary(),
        }
    }
}

/// The bytes of a `.vdb` file holding `grids` (in order) and the file-level metadata.
/// The same grids give the same bytes, for any thread count.
pub fn encode(grids: &[AnyGrid<'_>], file_metadata: &Metadata) -> Vec<u8> {
    let mut out = Vec::new();
    encode_into(grids, file_metadata, &mut out);
    out
}

/// [`encode`] into `out`, which is cleared first (its capacity is reused).
pub fn encode_into(grids: &[AnyGrid<'_>], file_metadata: &Metadata, out: &mut Vec<u8>) {
    out.clear();
    // Header (`Archive::writeHeader`); the UUID is filled in last.
    out.extend_from_slice(&MAGIC.to_le_bytes());
    put_u32(out, FILE_VERSION);
    put_u32(out, LIBRARY_VERSION[0]);
    put_u32(out, LIBRARY_VERSION[1]);
    out.push(1); // hasGridOffsets: the stream positions below are real
    debug_assert_eq!(out.len(), UUID_AT);
    out.extend_from_slice(&[b'0'; UUID_LEN]);
    file_metadata.write(out);
    put_u32(out, grids.len() as u32);
    let names = unique_names(grids);
    for (grid, unique) in grids.iter().zip(&names) {
        match grid {
            AnyGrid::Float(g) => encode_grid(g, unique, out),
            AnyGrid::Vec3(g) => encode_grid(g, unique, out),
        }
    }
    let uuid = uuid_of(&out[UUID_AT + UUID_LEN..]);
    out[UUID_AT..UUID_AT + UUID_LEN].copy_from_slice(&uuid);
}

/// Descriptor names as `Archive::write` makes them unique: a name that is empty or
/// shared by several grids gets the suffix "\x1e0", then "\x1e1", ... until unused
/// (`GridDescriptor::addSuffix`).
fn unique_names(grids: &[AnyGrid<'_>]) -> Vec<String> {
    let mut count: HashMap<&str, usize> = HashMap::new();
    for g in grids {
        *count.entry(g.name()).or_default() += 1;
    }
    let mut used = std::collections::HashSet::new();
    let mut names = Vec::with_capacity(grids.len());
    for g in grids {
        let base = g.name();
        let mut name = base.to_owned();
        if base.is_empty() || count[base] > 1 {
            name = format!("{base}\x1e0");
        }
        let mut n = 1;
        while used.contains(&name) {
            name = format!("{base}\x1e{n}");
            n += 1;
        }
        used.insert(name.clone());
        names.push(name);
    }
    names
}

/// A leaf's value mask: bit `n % 64` of word `n / 64` is set where value `n` is non-zero
/// (`util/NodeMasks.h`). Word `w` holds the voxels with x = w.
#[inline]
fn leaf_mask<T: Voxel>(leaf: &[T; LEAF_VOXELS]) -> [u64; 8] {
    let mut mask = [0u64; 8];
    for (word, chunk) in mask.iter_mut().zip(leaf.chunks_exact(64)) {
        let mut m = 0u64;
        for (bit, v) in chunk.iter().enumerate() {
            m |= u64::from(!v.is_zero()) << bit;
        }
        *word = m;
    }
    mask
}

/// The sort key of a leaf: root child (by x, then y, then z, as `std::map<Coord>`), then
/// the child offset in the 32³ node, then in the 16³ node (`InternalNode::coordToOffset`).
#[inline]
fn tree_key(o: [i32; 3]) -> ([i32; 3], u32, u32) {
    ([o[0] >> OUTER_TOTAL, o[1] >> OUTER_TOTAL, o[2] >> OUTER_TOTAL], outer_offset(o), inner_offset(o))
}

/// A child's offset in its 32³ internal node.
#[inline]
fn outer_offset(o: [i32; 3]) -> u32 {
    let c = |v: i32| ((v as u32) & ((1 << OUTER_TOTAL) - 1)) >> INNER_TOTAL;
    (c(o[0]) << (2 * OUTER_LOG2)) | (c(o[1]) << OUTER_LOG2) | c(o[2])
}

/// A leaf's offset in its 16³ internal node.
#[inline]
fn inner_offset(o: [i32; 3]) -> u32 {
    let c = |v: i32| ((v as u32) & ((1 << INNER_TOTAL) - 1)) >> LEAF_LOG2;
    (c(o[0]) << (2 * INNER_LOG2)) | (c(o[1]) << INNER_LOG2) | c(o[2])
}

/// The root child holding a leaf: its origin, the leaf origin rounded down to 4096.
#[inline]
fn root_origin(o: [i32; 3]) -> [i32; 3] {
    const M: i32 = !((1 << OUTER_TOTAL) - 1);
    [o[0] & M, o[1] & M, o[2] & M]
}

/// Leaves per parallel task when writing leaf buffers.
const LEAVES_PER_TASK: usize = 256;

/// One grid: descriptor, stream positions, then the grid (`Archive::writeGrid`).
fn encode_grid<T: Voxel>(grid: &Grid<T>, unique_name: &str, out: &mut Vec<u8>) {
    let masks: Vec<[u64; 8]> = grid.leaves.par_iter().with_min_len(64).map(leaf_mask).collect();
    let mut order: Vec<u32> = (0..masks.len() as u32).filter(|&i| masks[i as usize] != [0; 8]).collect();
    order.sort_unstable_by_key(|&i| tree_key(grid.origins[i as usize]));
    let counts: Vec<u32> =
        order.iter().map(|&i| masks[i as usize].iter().map(|w| w.count_ones()).sum()).collect();
    let buffer_bytes: Vec<usize> =
        counts.iter().map(|&c| LEAF_MASK_BYTES + 1 + c as usize * T::BYTES).collect();

    // GridDescriptor::writeHeader and writeStreamPos (patched below).
    put_str(out, unique_name);
    put_str(out, T::TREE_TYPE);
    put_str(out, ""); // instance parent: none
    let positions_at = out.len();
    out.extend_from_slice(&[0; 24]);
    let grid_pos = out.len();

    put_u32(out, COMPRESS_ACTIVE_MASK);
    grid_metadata(grid, &order, &masks, &counts).write(out);
    grid.transform.write(out);
    write_topology(grid, &order, &masks, out);
    let block_pos = out.len();

    // Leaf buffers (`LeafNode::writeBuffers`), in topology order, written in parallel
    // into places fixed by the leaf sizes.
    let total: usize = buffer_bytes.iter().sum();
    out.reserve(total + 1024);
    out.resize(block_pos + total, 0);
    let mut rest = &mut out[block_pos..];
    let mut tasks = Vec::with_capacity(order.len().div_ceil(LEAVES_PER_TASK));
    for (leaves, sizes) in order.chunks(LEAVES_PER_TASK).zip(buffer_bytes.chunks(LEAVES_PER_TASK)) {
        let (dst, tail) = std::mem::take(&mut rest).split_at_mut(sizes.iter().sum());
        tasks.push((leaves, sizes, dst));
        rest = tail;
    }
    tasks.into_par_iter().for_each(|(leaves, sizes, dst)| {
        let mut at = 0;
        for (&i, &size) in leaves.iter().zip(sizes) {
            write_leaf_buffer(&grid.leaves[i as usize], &masks[i as usize], &mut dst[at..at + size]);
            at += size;
        }
    });
    let end_pos = out.len();

    let mut positions = [0u8; 24];
    positions[0..8].copy_from_slice(&(grid_pos as i64).to_le_bytes());
    positions[8..16].copy_from_slice(&(block_pos as i64).to_le_bytes());
    positions[16..24].copy_from_slice(&(end_pos as i64).to_le_bytes());
    out[positions_at..positions_at + 24].copy_from_slice(&positions);
}

/// A leaf's buffer: its value mask, the metadata byte, its active values in offset order
/// (`writeCompressedValues` with `COMPRESS_ACTIVE_MASK`). `dst` has exactly its size.
#[inline]
fn write_leaf_buffer<T: Voxel>(leaf: &[T; LEAF_VOXELS], mask: &[u64; 8], dst: &mut [u8]) {
    for (d, w) in dst[..LEAF_MASK_BYTES].chunks_exact_mut(8).zip(mask) {
        d.copy_from_slice(&w.to_le_bytes());
    }
    dst[LEAF_MASK_BYTES] = NO_MASK_OR_INACTIVE_VALS;
    let mut values = dst[LEAF_MASK_BYTES + 1..].chunks_exact_mut(T::BYTES);
    for (w, &word) in mask.iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            let n = w * 64 + bits.trailing_zeros() as usize;
            if let Some(d) = values.next() {
                leaf[n].write_le(d);
            }
            bits &= bits - 1;
        }
    }
}

/// The tree's topology (`Tree::writeTopology`, `RootNode::writeTopology`,
/// `InternalNode::writeTopology`, `LeafNode::writeTopology`); `order` is the non-empty
/// leaves sorted by [`tree_key`].
fn write_topology<T: Voxel>(grid: &Grid<T>, order: &[u32], masks: &[[u64; 8]], out: &mut Vec<u8>) {
    let origin = |k: usize| grid.origins[order[k] as usize];
    put_u32(out, 1); // buffer count
    let mut zero = [0u8; 12];
    T::ZERO.write_le(&mut zero);
    out.extend_from_slice(&zero[..T::BYTES]); // background
    let roots = runs(order.len(), |a, b| root_origin(origin(a)) == root_origin(origin(b)));
    put_u32(out, 0); // tiles
    put_u32(out, roots.len() as u32); // children
    for root in roots {
        let r = root_origin(origin(root.start));
        r.iter().for_each(|c| out.extend_from_slice(&c.to_le_bytes()));
        // The 32³ node: child mask, value mask (no tiles), metadata byte, no values.
        let inners = runs(root.len(), |a, b| {
            outer_offset(origin(root.start + a)) == outer_offset(origin(root.start + b))
        });
        let mut child_mask = vec![0u64; OUTER_MASK_BYTES / 8];
        for inner in &inners {
            let n = outer_offset(origin(root.start + inner.start)) as usize;
            child_mask[n / 64] |= 1 << (n % 64);
        }
        put_words(out, &child_mask);
        out.resize(out.len() + OUTER_MASK_BYTES, 0);
        out.push(NO_MASK_OR_INACTIVE_VALS);
        for inner in inners {
            let leaves = root.start + inner.start..root.start + inner.end;
            // The 16³ node, then its leaves' value masks.
            let mut child_mask = [0u64; INNER_MASK_BYTES / 8];
            for k in leaves.clone() {
                let n = inner_offset(origin(k)) as usize;
                child_mask[n / 64] |= 1 << (n % 64);
            }
            put_words(out, &child_mask);
            out.resize(out.len() + INNER_MASK_BYTES, 0);
            out.push(NO_MASK_OR_INACTIVE_VALS);
            for k in leaves {
                put_words(out, &masks[order[k] as usize]);
            }
        }
    }
}

/// The maximal runs of `0..n` whose neighbours are `same`.
fn runs(n: usize, same: impl Fn(usize, usize) -> bool) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=n {
        if k == n || !same(k - 1, k) {
            if start < k {
                out.push(start..k);
            }
            start = k;
        }
    }
    out
}

/// The grid's metadata as OpenVDB writes it with grid statistics on (`Archive::writeGrid`,
/// `GridBase::addStatsMetadata`): the caller's entries, `name`, `class`, the active voxel
/// bounding box, `file_compression`, `file_mem_bytes` and `file_voxel_count`.
fn grid_metadata<T: Voxel>(grid: &Grid<T>, order: &[u32], masks: &[[u64; 8]], counts: &[u32]) -> Metadata {
    let (lo, hi) = active_bbox(grid, order, masks);
    let voxels: u64 = counts.iter().map(|&c| u64::from(c)).sum();
    let inner_nodes = runs(order.len(), |a, b| {
        let (p, q) = (grid.origins[order[a] as usize], grid.origins[order[b] as usize]);
        root_origin(p) == root_origin(q) && outer_offset(p) == outer_offset(q)
    })
    .len();
    let outer_nodes = runs(order.len(), |a, b| {
        root_origin(grid.origins[order[a] as usize]) == root_origin(grid.origins[order[b] as usize])
    })
    .len();
    let mut m = grid.metadata.clone();
    m.entries.insert("name".into(), MetaValue::String(grid.name.clone()));
    m.entries.insert("class".into(), MetaValue::String(grid.class.as_str().into()));
    m.entries.insert("file_bbox_min".into(), MetaValue::Vec3i(lo));
    m.entries.insert("file_bbox_max".into(), MetaValue::Vec3i(hi));
    m.entries.insert("file_compression".into(), MetaValue::String("active values".into()));
    let mem = mem_bytes::<T>(outer_nodes as u64, inner_nodes as u64, order.len() as u64);
    m.entries.insert("file_mem_bytes".into(), MetaValue::Int64(mem as i64));
    m.entries.insert("file_voxel_count".into(), MetaValue::Int64(voxels as i64));
    m
}

/// What OpenVDB 10 on x86-64 reports as the tree's `memUsage` once loaded (measured
/// `sizeof`s; `Tree::memUsage`, `RootNode::memUsage`, `InternalNode::memUsage`,
/// `LeafNode::memUsage`).
fn mem_bytes<T: Voxel>(outer_nodes: u64, inner_nodes: u64, leaves: u64) -> u64 {
    let [tree, root, entry, leaf] = T::MEM_SIZES;
    let node = |log2: u32| {
        let n = 1u64 << (3 * log2);
        n * entry + 2 * (n / 8) + 12
    };
    tree + root
        + outer_nodes * node(OUTER_LOG2)
        + inner_nodes * node(INNER_LOG2)
        + leaves * (leaf + LEAF_VOXELS as u64 * T::BYTES as u64)
}

/// The bounding box of the active voxels, inclusive; OpenVDB's empty `CoordBBox`
/// (max, min) for a grid with none.
fn active_bbox<T: Voxel>(grid: &Grid<T>, order: &[u32], masks: &[[u64; 8]]) -> ([i32; 3], [i32; 3]) {
    let mut lo = [i32::MAX; 3];
    let mut hi = [i32::MIN; 3];
    for &i in order {
        let o = grid.origins[i as usize];
        let m = &masks[i as usize];
        // x is the word; y the byte of the OR of the words; z the bit of the OR of its bytes.
        let xs: u32 = m.iter().enumerate().filter(|(_, w)| **w != 0).fold(0, |a, (x, _)| a | 1 << x);
        let any = m.iter().fold(0u64, |a, w| a | w);
        let ys: u32 = (0..8).filter(|y| (any >> (8 * y)) & 0xff != 0).fold(0, |a, y| a | 1 << y);
        let zs: u32 = (0..8).fold(0u64, |a, y| a | (any >> (8 * y)) & 0xff) as u32;
        for (a, bits) in [xs, ys, zs].into_iter().enumerate() {
            lo[a] = lo[a].min(o[a] + bits.trailing_zeros() as i32);
            hi[a] = hi[a].max(o[a] + 31 - bits.leading_zeros() as i32);
        }
    }
    (lo, hi)
}

/// The header's 36-character UUID from a hash of the file after it: lowercase hex in
/// 8-4-4-4-12 groups (as OpenVDB 10 writes its random ones), marked as an RFC 9562
/// version 8 (custom) UUID.
fn uuid_of(content: &[u8]) -> [u8; UUID_LEN] {
    let [a, b] = content_hash(content);
    let mut bits = (u128::from(a) << 64) | u128::from(b);
    bits = (bits & !(0xf << 76)) | (0x8 << 76); // version 8
    bits = (bits & !(0x3 << 62)) | (0x2 << 62); // variant 10
    let hex = b"0123456789abcdef";
    let mut out = [b'-'; UUID_LEN];
    let mut nibble = 0;
    for (k, c) in out.iter_mut().enumerate() {
        if matches!(k, 8 | 13 | 18 | 23) {
            continue;
        }
        *c = hex[((bits >> (124 - 4 * nibble)) & 0xf) as usize];
        nibble += 1;
    }
    out
}

/// Bytes per block hashed in parallel.
const HASH_BLOCK: usize = 1 << 20;

/// A 128-bit hash of `bytes`: fixed 1 MiB blocks hashed in parallel by four
/// multiply-rotate lanes (xxHash64's round), their digests folded in order. Not
/// cryptographic: it only has to make different files' UUIDs differ.
fn content_hash(bytes: &[u8]) -> [u64; 2] {
    let blocks: Vec<[u64; 2]> = bytes.par_chunks(HASH_BLOCK).map(block_hash).collect();
    let mut h = [mix(bytes.len() as u64 ^ 0x243f_6a88_85a3_08d3), mix(bytes.len() as u64)];
    for d in blocks {
        h[0] = mix(h[0] ^ d[0]).wrapping_add(d[1]);
        h[1] = mix(h[1].rotate_left(23) ^ d[1]).wrapping_add(d[0]);
    }
    [mix(h[0] ^ h[1].rotate_left(32)), mix(h[1] ^ h[0])]
}

const P1: u64 = 0x9E37_79B1_85EB_CA87;
const P2: u64 = 0xC2B2_AE3D_27D4_EB4F;

#[inline(always)]
fn lane(acc: u64, word: u64) -> u64 {
    acc.wrapping_add(word.wrapping_mul(P2)).rotate_left(31).wrapping_mul(P1)
}

#[inline(always)]
fn le_u64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

/// SplitMix64's finaliser.
#[inline]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn block_hash(block: &[u8]) -> [u64; 2] {
    let mut acc = [P1.wrapping_add(P2), P2, 0, P1.wrapping_neg()];
    let mut stripes = block.chunks_exact(32);
    for s in &mut stripes {
        acc[0] = lane(acc[0], le_u64(&s[0..8]));
        acc[1] = lane(acc[1], le_u64(&s[8..16]));
        acc[2] = lane(acc[2], le_u64(&s[16..24]));
        acc[3] = lane(acc[3], le_u64(&s[24..32]));
    }
    let mut tail = 0u64;
    for (k, &b) in stripes.remainder().iter().enumerate() {
        tail = lane(tail ^ k as u64, u64::from(b));
    }
    let a = mix(acc[0] ^ acc[1].rotate_left(7) ^ acc[2].rotate_left(12) ^ acc[3].rotate_left(18) ^ tail);
    let b = mix(acc[3] ^ acc[2].rotate_left(29) ^ acc[1].rotate_left(41) ^ acc[0].rotate_left(53) ^ !tail);
    [a, b ^ block.len() as u64]
}

#[inline]
fn put_u32(w: &mut Vec<u8>, v: u32) {
    w.extend_from_slice(&v.to_le_bytes());
}

/// `writeString`: a 32-bit length, then the bytes (lengths checked on insertion).
#[inline]
fn put_str(w: &mut Vec<u8>, s: &str) {
    put_u32(w, s.len() as u32);
    w.extend_from_slice(s.as_bytes());
}

#[inline]
fn put_f64s(w: &mut Vec<u8>, v: &[f64]) {
    v.iter().for_each(|c| w.extend_from_slice(&c.to_le_bytes()));
}

/// A node mask's words (`NodeMask::save`).
#[inline]
fn put_words(w: &mut Vec<u8>, words: &[u64]) {
    words.iter().for_each(|x| w.extend_from_slice(&x.to_le_bytes()));
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Transform {
        Transform::new(1.0, [0.0; 3]).unwrap()
    }

    /// Appended leaves are the same grid as leaves made voxel by voxel; a clash adds
    /// nothing and keeps the grid as it was.
    #[test]
    fn appended_leaves_equal_voxels_set_one_by_one() {
        let mut a = Grid::<f32>::new("d", unit(), GridClass::FogVolume);
        a.set([3, 0, 0], 2.0);
        let leaves = a.append_leaves(&[[8, 0, 0], [-8, 16, 0]]).unwrap();
        assert!(leaves.iter().flatten().all(|&v| v == 0.0));
        leaves[0][Grid::<f32>::leaf_offset([9, 1, 2])] = 5.0;
        leaves[1][Grid::<f32>::leaf_offset([-7, 16, 0])] = 6.0;
        let mut b = Grid::<f32>::new("d", unit(), GridClass::FogVolume);
        b.set([-7, 16, 0], 6.0);
        b.set([9, 1, 2], 5.0);
        b.set([3, 0, 0], 2.0);
        assert_eq!(encode(&[(&a).into()], &Metadata::new()), encode(&[(&b).into()], &Metadata::new()));
        // Clashes: an origin already there, a repeated one, one that is not a leaf origin.
        for bad in [&[[16, 0, 0], [0, 0, 0]][..], &[[24, 0, 0], [24, 0, 0]], &[[1, 0, 0]]] {
            assert!(a.append_leaves(bad).is_none(), "{bad:?}");
        }
        assert_eq!(a.get([3, 0, 0]), 2.0);
        a.add([3, 0, 0], 1.0);
        assert_eq!(a.get([3, 0, 0]), 3.0);
        assert_eq!(a.leaf_count(), 3);
        assert_eq!(encode(&[(&a).into()], &Metadata::new()), {
            b.add([3, 0, 0], 1.0);
            encode(&[(&b).into()], &Metadata::new())
        });
    }

    /// A reader of the bytes written, for the layout checks.
    struct Cursor<'a> {
        bytes: &'a [u8],
        at: usize,
    }

    impl<'a> Cursor<'a> {
        fn take(&mut self, n: usize) -> &'a [u8] {
            let s = &self.bytes[self.at..self.at + n];
            self.at += n;
            s
        }
        fn u8(&mut self) -> u8 {
            self.take(1)[0]
        }
        fn u32(&mut self) -> u32 {
            u32::from_le_bytes(self.take(4).try_into().unwrap())
        }
        fn i32(&mut self) -> i32 {
            i32::from_le_bytes(self.take(4).try_into().unwrap())
        }
        fn i64(&mut self) -> i64 {
            i64::from_le_bytes(self.take(8).try_into().unwrap())
        }
        fn f32(&mut self) -> f32 {
            f32::from_le_bytes(self.take(4).try_into().unwrap())
        }
        fn f64(&mut self) -> f64 {
            f64::from_le_bytes(self.take(8).try_into().unwrap())
        }
        fn str(&mut self) -> &'a str {
            let n = self.u32() as usize;
            std::str::from_utf8(self.take(n)).unwrap()
        }
        fn words(&mut self, n: usize) -> Vec<u64> {
            (0..n).map(|_| u64::from_le_bytes(self.take(8).try_into().unwrap())).collect()
        }
        /// One metadata entry: name, type, size, raw value.
        fn meta(&mut self) -> (&'a str, &'a str, &'a [u8]) {
            let name = self.str();
            let ty = self.str();
            let n = self.u32() as usize;
            (name, ty, self.take(n))
        }
    }

    /// Every byte of a file with one float voxel, computed by hand from the format:
    /// header, empty file metadata, one descriptor whose three positions point at the
    /// grid, its metadata and transform, the topology of one branch down to one leaf,
    /// and that leaf's buffer.
    #[test]
    fn one_voxel_file_has_the_layout_of_the_format() {
        let t = Transform::new(0.01, [0.1, 0.2, 0.3]).unwrap();
        let mut g = Grid::<f32>::new("density", t, GridClass::FogVolume);
        g.set([1, 2, 3], 5.0);
        let bytes = encode(&[AnyGrid::from(&g)], &Metadata::new());
        let mut c = Cursor { bytes: &bytes, at: 0 };
        assert_eq!(c.take(8), &[0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0]); // " BDV" as int64
        assert_eq!(c.u32(), 224);
        assert_eq!((c.u32(), c.u32()), (10, 0));
        assert_eq!(c.u8(), 1); // has grid offsets
        let uuid = std::str::from_utf8(c.take(36)).unwrap();
        assert_eq!(uuid.len(), 36);
        for (k, ch) in uuid.chars().enumerate() {
            assert_eq!(ch == '-', matches!(k, 8 | 13 | 18 | 23), "{uuid}");
            assert!(ch == '-' || ch.is_ascii_hexdigit() && !ch.is_ascii_uppercase(), "{uuid}");
        }
        assert_eq!(c.at, 57);
        assert_eq!(c.u32(), 0); // file metadata: none
        assert_eq!(c.u32(), 1); // one grid
        assert_eq!(c.str(), "density");
        assert_eq!(c.str(), "Tree_float_5_4_3");
        assert_eq!(c.str(), ""); // no instance parent
        let (grid_pos, block_pos, end_pos) = (c.i64() as usize, c.i64() as usize, c.i64() as usize);
        assert_eq!(grid_pos, c.at, "the grid starts right after its positions");
        assert_eq!(c.u32(), 2); // COMPRESS_ACTIVE_MASK
        assert_eq!(c.u32(), 7); // metadata entries, in name order
        assert_eq!(c.meta(), ("class", "string", &b"fog volume"[..]));
        let vec3i = |v: [i32; 3]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        assert_eq!(c.meta(), ("file_bbox_max", "vec3i", &vec3i([1, 2, 3])[..]));
        assert_eq!(c.meta(), ("file_bbox_min", "vec3i", &vec3i([1, 2, 3])[..]));
        assert_eq!(c.meta(), ("file_compression", "string", &b"active values"[..]));
        // OpenVDB 10 reports 307,600 bytes for this tree (its own file of it says so).
        assert_eq!(c.meta(), ("file_mem_bytes", "int64", &307_600i64.to_le_bytes()[..]));
        assert_eq!(c.meta(), ("file_voxel_count", "int64", &1i64.to_le_bytes()[..]));
        assert_eq!(c.meta(), ("name", "string", &b"density"[..]));
        assert_eq!(c.str(), "UniformScaleTranslateMap");
        let v3 = |c: &mut Cursor| [c.f64(), c.f64(), c.f64()];
        assert_eq!(v3(&mut c), [0.1, 0.2, 0.3]); // translation
        assert_eq!(v3(&mut c), [0.01; 3]); // scale
        assert_eq!(v3(&mut c), [0.01; 3]); // voxel size
        assert_eq!(v3(&mut c), [1.0 / 0.01; 3]);
        assert_eq!(v3(&mut c), [(1.0 / 0.01) * (1.0 / 0.01); 3]);
        assert_eq!(v3(&mut c), [(1.0 / 0.01) / 2.0; 3]);
        // Topology.
        assert_eq!(c.u32(), 1); // buffer count
        assert_eq!(c.f32(), 0.0); // background
        assert_eq!((c.u32(), c.u32()), (0, 1)); // tiles, children
        assert_eq!([c.i32(), c.i32(), c.i32()], [0, 0, 0]); // root child origin
        let mut one_bit = vec![0u64; 512];
        one_bit[0] = 1;
        assert_eq!(c.words(512), one_bit); // 32³ child mask: child 0
        assert_eq!(c.words(512), vec![0; 512]); // no tiles
        assert_eq!(c.u8(), 0); // NO_MASK_OR_INACTIVE_VALS, then no active values
        let mut one_bit = vec![0u64; 64];
        one_bit[0] = 1;
        assert_eq!(c.words(64), one_bit); // 16³ child mask: leaf 0
        assert_eq!(c.words(64), vec![0; 64]);
        assert_eq!(c.u8(), 0);
        // The leaf's value mask: offset 1·64 + 2·8 + 3 = 83 is bit 19 of word 1.
        let leaf_mask = vec![0, 1 << 19, 0, 0, 0, 0, 0, 0];
        assert_eq!(c.words(8), leaf_mask);
        assert_eq!(block_pos, c.at, "the buffers start after the topology");
        assert_eq!(c.words(8), leaf_mask);
        assert_eq!(c.u8(), 0);
        assert_eq!(c.f32(), 5.0);
        assert_eq!(end_pos, c.at, "the grid ends after its one value");
        assert_eq!(c.at, bytes.len());
    }

    /// Reads a leaf buffer section back: (mask, active values as raw bytes).
    fn leaf_buffers(bytes: &[u8], grid: usize, value_bytes: usize) -> Vec<(Vec<u64>, Vec<u8>)> {
        // Walk to the grid's descriptor, then jump with its positions.
        let mut c = Cursor { bytes, at: 57 };
        let n = c.u32();
        for _ in 0..n {
            c.meta();
        }
        c.u32();
        let mut block_end = (0, 0);
        for k in 0..=grid {
            c.str();
            c.str();
            c.str();
            let (_, block, end) = (c.i64(), c.i64() as usize, c.i64() as usize);
            block_end = (block, end);
            if k < grid {
                c.at = end;
            }
        }
        let mut c = Cursor { bytes, at: block_end.0 };
        let mut out = Vec::new();
        while c.at < block_end.1 {
            let mask = c.words(8);
            assert_eq!(c.u8(), 0);
            let count: u32 = mask.iter().map(|w| w.count_ones()).sum();
            out.push((mask, c.take(count as usize * value_bytes).to_vec()));
        }
        assert_eq!(c.at, block_end.1);
        out
    }

    #[test]
    fn masks_have_a_bit_per_voxel_in_x_y_z_order() {
        let mut g = Grid::<f32>::new("m", unit(), GridClass::Unknown);
        // Leaf at the origin: (0,0,0) bit 0; (0,0,7) bit 7; (0,1,0) bit 8; (1,0,0) word 1;
        // (7,7,7) bit 63 of word 7.
        for (ijk, v) in
            [([0, 0, 7], 2.0), ([7, 7, 7], 5.0), ([1, 0, 0], 4.0), ([0, 1, 0], 3.0), ([0, 0, 0], 1.0)]
        {
            g.set(ijk, v);
        }
        let bytes = encode(&[AnyGrid::from(&g)], &Metadata::new());
        let leaves = leaf_buffers(&bytes, 0, 4);
        assert_eq!(leaves.len(), 1);
        assert_eq!(leaves[0].0, vec![1 | 1 << 7 | 1 << 8, 1, 0, 0, 0, 0, 0, 1 << 63]);
        let values: Vec<f32> =
            leaves[0].1.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
        assert_eq!(values, vec![1.0, 2.0, 3.0, 4.0, 5.0], "values in offset order");
        assert_eq!(Grid::<f32>::leaf_offset([-1, -8, -3]), 7 * 64 + 5);
        assert_eq!(Grid::<f32>::leaf_origin([-1, -8, -9]), [-8, -8, -16]);
    }

    #[test]
    fn leaves_are_written_in_openvdb_tree_order() {
        let mut g = Grid::<f32>::new("o", unit(), GridClass::Unknown);
        // Root children sorted by (x, y, z) of their origins, negative first; inside a
        // node by offset x·dim² + y·dim + z.
        let points = [
            [5000, 0, 0],
            [-5000, 3, 0],
            [0, -1, 0],
            [0, 0, 8],
            [8, 0, 0],
            [0, 8, 0],
            [0, 0, 0],
            [0, 0, 128],
        ];
        for (k, p) in points.iter().enumerate() {
            g.set(*p, k as f32 + 1.0);
        }
        let bytes = encode(&[AnyGrid::from(&g)], &Metadata::new());
        let values: Vec<f32> = leaf_buffers(&bytes, 0, 4)
            .iter()
            .map(|(_, v)| f32::from_le_bytes(v[..4].try_into().unwrap()))
            .collect();
        // -5000 (root x -8192); (0,-1,0) (root y -4096); then root (0,0,0): its 32³ node
        // holds (0,0,0)..(0,0,128) in two 16³ children, offset 0 then 1; within child 0
        // leaves (0,0,0), (0,0,8), (0,8,0), (8,0,0); then root x 4096.
        assert_eq!(values, vec![2.0, 3.0, 7.0, 4.0, 6.0, 5.0, 8.0, 1.0]);
    }

    #[test]
    fn the_same_grid_built_in_another_order_gives_the_same_bytes() {
        let mut points = Vec::new();
        let mut s = crate::rng::Stream::new(7, crate::rng::Purpose::named("vdb.test"), 0);
        for _ in 0..5000 {
            let p = [0, 1, 2].map(|_| (s.below(4000) as i32) - 2000);
            points.push((p, s.uniform(0.5, 2.0)));
        }
        let build = |pts: &[([i32; 3], f32)]| {
            let mut g = Grid::<f32>::new("d", unit(), GridClass::FogVolume);
            let mut v = Grid::<[f32; 3]>::new("v", unit(), GridClass::Unknown);
            for &(p, x) in pts {
                g.set(p, x);
                v.set(p, [x, -x, 0.0]);
            }
            encode(&[AnyGrid::from(&g), AnyGrid::from(&v)], &Metadata::new())
        };
        let a = build(&points);
        points.reverse();
        let b = build(&points);
        points.sort_by_key(|&(p, _)| (p[2], p[0], p[1]));
        let c = build(&points);
        assert_eq!(a, b);
        assert_eq!(a, c);
    }

    #[test]
    fn voxels_read_back_what_was_added_through_the_leaf_cache() {
        // Points in a small box, so leaves recur and share cache slots; then clear.
        let mut s = crate::rng::Stream::new(9, crate::rng::Purpose::named("vdb.cache"), 0);
        let mut g = Grid::<f32>::new("c", unit(), GridClass::Unknown);
        let mut want: HashMap<[i32; 3], f32> = HashMap::new();
        for _ in 0..20_000 {
            let p = [0, 1, 2].map(|_| s.below(200) as i32 - 100);
            g.add(p, 1.0);
            *want.entry(p).or_default() += 1.0;
        }
        assert_eq!(g.active_voxel_count(), want.len() as u64);
        for (p, v) in &want {
            assert_eq!(g.get(*p), *v, "{p:?}");
        }
        g.clear();
        assert_eq!((g.leaf_count(), g.get([0, 0, 0])), (0, 0.0));
        g.add([0, 0, 0], 2.0);
        assert_eq!((g.leaf_count(), g.get([0, 0, 0])), (1, 2.0));
    }

    #[test]
    fn bytes_are_identical_for_any_thread_count() {
        let mut g = Grid::<f32>::new("d", unit(), GridClass::FogVolume);
        for k in 0..700_000i32 {
            g.set([k % 97, (k / 97) % 101, k / (97 * 101) * 3], (k % 13) as f32 + 0.5);
        }
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| encode(&[AnyGrid::from(&g)], &Metadata::new()))
        };
        let one = run(1);
        assert!(one.len() > 2 * HASH_BLOCK, "spans several hash blocks");
        assert_eq!(one, run(3));
        assert_eq!(one, run(8));
    }

    #[test]
    fn vec3_grids_write_three_floats_per_active_voxel() {
        let mut v = Grid::<[f32; 3]>::new("emission", unit(), GridClass::Unknown);
        v.set([-1, -1, -1], [1.0, 2.0, 3.0]);
        v.set([-1, -1, -2], [0.0, 0.0, 4.0]); // one non-zero component is active
        v.set([-1, -1, -3], [0.0, 0.0, 0.0]); // zero is not
        assert_eq!(v.active_voxel_count(), 2);
        let bytes = encode(&[AnyGrid::from(&v)], &Metadata::new());
        let leaves = leaf_buffers(&bytes, 0, 12);
        assert_eq!(leaves.len(), 1);
        // (-1,-1,-1) is local (7,7,7) = 511, (-1,-1,-2) local (7,7,6) = 510.
        assert_eq!(leaves[0].0, vec![0, 0, 0, 0, 0, 0, 0, 3 << 62]);
        let floats: Vec<f32> =
            leaves[0].1.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
        assert_eq!(floats, vec![0.0, 0.0, 4.0, 1.0, 2.0, 3.0]);
        let type_at = bytes.windows(16).position(|w| w == b"Tree_vec3s_5_4_3");
        assert!(type_at.is_some());
    }

    #[test]
    fn stream_positions_chain_from_grid_to_grid() {
        let mut a = Grid::<f32>::new("a", unit(), GridClass::FogVolume);
        a.set([0, 0, 0], 1.0);
        let mut b = Grid::<[f32; 3]>::new("b", unit(), GridClass::Unknown);
        b.set([9, 9, 9], [1.0, 1.0, 1.0]);
        b.insert_metadata("units", "W/m^3/sr").unwrap();
        let mut file = Metadata::new();
        file.insert("creator", "phenomena").unwrap();
        let bytes = encode(&[AnyGrid::from(&a), AnyGrid::from(&b)], &file);
        let mut c = Cursor { bytes: &bytes, at: 57 };
        assert_eq!(c.u32(), 1);
        assert_eq!(c.meta(), ("creator", "string", &b"phenomena"[..]));
        assert_eq!(c.u32(), 2);
        for name in ["a", "b"] {
            assert_eq!(c.str(), name);
            c.str();
            c.str();
            let (grid, block, end) = (c.i64() as usize, c.i64() as usize, c.i64() as usize);
            assert_eq!(grid, c.at);
            assert!(grid < block && block < end);
            c.at = end; // the next descriptor follows the grid
        }
        assert_eq!(c.at, bytes.len());
    }

    #[test]
    fn an_empty_grid_has_only_a_root_and_openvdbs_empty_bbox() {
        let g = Grid::<f32>::new("", unit(), GridClass::Unknown);
        let bytes = encode(&[AnyGrid::from(&g)], &Metadata::new());
        let mut c = Cursor { bytes: &bytes, at: 57 + 8 };
        assert_eq!(c.str(), "\x1e0", "an empty name gets a suffix, as Archive::write does");
        c.str();
        c.str();
        let (grid, block, end) = (c.i64() as usize, c.i64() as usize, c.i64() as usize);
        assert_eq!(grid, c.at);
        c.u32();
        assert_eq!(c.u32(), 7);
        assert_eq!(c.meta(), ("class", "string", &b"unknown"[..]));
        let (_, _, max) = c.meta();
        assert_eq!(max, [i32::MIN; 3].iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<_>>());
        let bytes_tail = &bytes[block - 16..];
        // buffer count 1, background 0, no tiles, no children; no buffers.
        assert_eq!(bytes_tail, [1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(block, end);
    }

    #[test]
    fn duplicate_names_get_openvdb_suffixes() {
        let g = Grid::<f32>::new("d", unit(), GridClass::Unknown);
        let h = Grid::<f32>::new("e", unit(), GridClass::Unknown);
        let names = unique_names(&[AnyGrid::from(&g), AnyGrid::from(&h), AnyGrid::from(&g)]);
        assert_eq!(names, vec!["d\x1e0", "e", "d\x1e1"]);
    }

    #[test]
    fn add_dense_equals_adding_voxel_by_voxel() {
        let dims = [11, 9, 21];
        let origin = [-5, 3, -13];
        let values: Vec<f32> = (0..dims[0] * dims[1] * dims[2]).map(|k| (k % 7) as f32).collect();
        let mut a = Grid::<f32>::new("a", unit(), GridClass::FogVolume);
        a.add_dense(origin, dims, &values).unwrap();
        a.add_dense(origin, dims, &values).unwrap();
        let mut b = Grid::<f32>::new("a", unit(), GridClass::FogVolume);
        for x in 0..dims[0] {
            for y in 0..dims[1] {
                for z in 0..dims[2] {
                    let p = [origin[0] + x as i32, origin[1] + y as i32, origin[2] + z as i32];
                    let v = values[(x * dims[1] + y) * dims[2] + z];
                    b.add(p, v);
                    b.add(p, v);
                }
            }
        }
        assert_eq!(a.active_voxel_count(), b.active_voxel_count());
        assert_eq!(a.get([0, 5, 0]), b.get([0, 5, 0]));
        assert_eq!(
            encode(&[AnyGrid::from(&a)], &Metadata::new()),
            encode(&[AnyGrid::from(&b)], &Metadata::new())
        );
        assert!(matches!(a.add_dense(origin, dims, &values[1..]), Err(VdbError::DenseLength { .. })));
        assert!(matches!(
            a.add_dense([i32::MAX - 1, 0, 0], [3, 1, 1], &[1.0; 3]),
            Err(VdbError::DenseOutOfRange { .. })
        ));
    }

    #[test]
    fn bbox_and_counts_cover_every_active_voxel() {
        let mut g = Grid::<f32>::new("b", unit(), GridClass::FogVolume);
        let pts = [[-5000, 7, 3], [5000, -9, 4], [12, 13, -14], [3, 2, 1]];
        for p in pts {
            g.set(p, 1.0);
        }
        g.set([3, 2, 1], 0.0); // inactive again: its leaf is empty and not written
        let order: Vec<u32> = {
            let masks: Vec<_> = g.leaves.iter().map(leaf_mask).collect();
            let mut o: Vec<u32> = (0..masks.len() as u32).filter(|&i| masks[i as usize] != [0; 8]).collect();
            o.sort_unstable_by_key(|&i| tree_key(g.origins[i as usize]));
            assert_eq!(active_bbox(&g, &o, &masks), ([-5000, -9, -14], [5000, 13, 4]));
            o
        };
        assert_eq!(order.len(), 3);
        assert_eq!(g.active_voxel_count(), 3);
    }

    #[test]
    fn metadata_refuses_empty_and_reserved_names() {
        let mut g = Grid::<f32>::new("b", unit(), GridClass::FogVolume);
        assert_eq!(g.insert_metadata("", 1.0f32), Err(VdbError::EmptyMetadataName));
        assert_eq!(g.insert_metadata("class", "x"), Err(VdbError::ReservedMetadataName("class".into())));
        assert!(g.insert_metadata("units", "K").is_ok());
        assert_eq!(g.metadata().get("units"), Some(&MetaValue::String("K".into())));
        assert!(Transform::new(0.0, [0.0; 3]).is_err());
        assert!(Transform::new(f64::NAN, [0.0; 3]).is_err());
        assert!(Transform::new(1e-300, [0.0; 3]).is_err());
        assert!(Transform::new(1.0, [f64::INFINITY, 0.0, 0.0]).is_err());
    }

    #[test]
    fn the_uuid_depends_on_the_content() {
        let mut g = Grid::<f32>::new("d", unit(), GridClass::FogVolume);
        g.set([0, 0, 0], 1.0);
        let a = encode(&[AnyGrid::from(&g)], &Metadata::new());
        g.set([0, 0, 0], 2.0);
        let b = encode(&[AnyGrid::from(&g)], &Metadata::new());
        assert_ne!(a[21..57], b[21..57]);
        assert_eq!(a[57..a.len() - 4], b[57..b.len() - 4]);
        assert_eq!(b[21 + 14], b'8', "version 8");
    }

    #[test]
    fn transform_maps_index_to_world_like_openvdb() {
        let t = Transform::new(0.5, [1.0, 2.0, 3.0]).unwrap();
        assert_eq!(t.index_to_world_m([2.0, -2.0, 0.0]), [2.0, 1.0, 3.0]);
        assert_eq!(t.world_to_index([2.0, 1.0, 3.0]), [2.0, -2.0, 0.0]);
    }
}
