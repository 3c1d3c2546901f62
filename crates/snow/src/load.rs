//! Scene meshes from files' bytes: Wavefront OBJ (tobj), glTF 2.0 / GLB (gltf) and DXF
//! 3DFACE entities (dxf, the paper's format). The caller reads the files (libraries do
//! no IO); each object, glTF mesh node or DXF layer becomes one object of the [`Mesh`].
//!
//! OBJ and glTF are y-up; DXF drawings are z-up and are turned so that their z becomes
//! our y (x stays, y becomes -z), keeping the handedness.

use glam::{Mat4, Vec3};
use gltf::accessor::{DataType, Dimensions};

use crate::mesh::{Cleaned, Mesh};

/// Why a mesh could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LoadError {
    /// The bytes are not a valid file of the format.
    #[error("not a valid {format} file: {message}")]
    Parse {
        /// OBJ, glTF or DXF.
        format: &'static str,
        /// The parser's message.
        message: String,
    },
    /// A glTF buffer the caller could not supply.
    #[error("the glTF buffer `{uri}` cannot be used: {reason}")]
    Buffer {
        /// The buffer's URI as written in the glTF file.
        uri: String,
        /// Why the caller could not supply it.
        reason: String,
    },
    /// No usable triangle.
    #[error(
        "no usable triangle ({non_finite} with non-finite vertices and {degenerate} degenerate ones dropped)"
    )]
    Empty {
        /// Triangles dropped for non-finite vertices.
        non_finite: usize,
        /// Triangles dropped as degenerate.
        degenerate: usize,
    },
}

/// A mesh read from a file, cleaned.
#[derive(Clone, Debug, PartialEq)]
pub struct Loaded {
    /// The triangles (y up, metres times the scale given).
    pub mesh: Mesh,
    /// What cleaning dropped (report it as a warning).
    pub cleaned: Cleaned,
    /// Object names, by object index.
    pub objects: Vec<String>,
}

/// Most triangles a mesh file may hold (about 1 GiB of vertices in a scene).
pub const MAX_TRIANGLES: usize = 20_000_000;

/// Most buffers a glTF file may name.
pub const MAX_BUFFERS: usize = 1024;

/// Triangles under this area are dropped as degenerate, m².
const MIN_AREA_M2: f32 = 1e-12;

fn finish(mut mesh: Mesh, objects: Vec<String>, scale: f32) -> Result<Loaded, LoadError> {
    for t in &mut mesh.triangles {
        for p in t.iter_mut() {
            *p *= scale;
        }
    }
    let cleaned = mesh.clean(MIN_AREA_M2);
    if mesh.is_empty() {
        return Err(LoadError::Empty { non_finite: cleaned.non_finite, degenerate: cleaned.degenerate });
    }
    Ok(Loaded { mesh, cleaned, objects })
}

/// Parse an OBJ file's bytes (materials ignored; faces triangulated).
pub fn obj(bytes: &[u8], scale: f32) -> Result<Loaded, LoadError> {
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    // Texture coordinates and normals are not used, and tobj 4.0.5 multiplies their face
    // indices unchecked (an overflow panic in debug builds, found by the OBJ fuzzer):
    // their statements are left out before parsing, so faces never index them.
    let kept: Vec<u8> = bytes
        .split_inclusive(|&b| b == b'\n')
        .filter(|line| {
            let first = std::str::from_utf8(line).ok().and_then(|l| l.split_whitespace().next());
            !matches!(first, Some("vt" | "vn"))
        })
        .flatten()
        .copied()
        .collect();
    let (models, _) = tobj::load_obj_buf(&mut std::io::Cursor::new(kept), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| LoadError::Parse { format: "OBJ", message: e.to_string() })?;
    let mut mesh = Mesh::default();
    let mut objects = Vec::new();
    for (o, model) in models.iter().enumerate() {
        let p = &model.mesh.positions;
        let vertex = |i: u32| -> Option<Vec3> {
            let i = i as usize * 3;
            (i + 2 < p.len()).then(|| Vec3::new(p[i], p[i + 1], p[i + 2]))
        };
        let mut tris = Vec::new();
        for t in model.mesh.indices.chunks_exact(3) {
            match (vertex(t[0]), vertex(t[1]), vertex(t[2])) {
                (Some(a), Some(b), Some(c)) => tris.push([a, b, c]),
                _ => {
                    return Err(LoadError::Parse {
                        format: "OBJ",
                        message: format!(
                            "face of object `{}` uses a vertex index past the vertex list",
                            model.name
                        ),
                    });
                }
            }
        }
        mesh.push_object(&tris, o as u32);
        objects.push(model.name.clone());
    }
    finish(mesh, objects, scale)
}

/// Parse glTF 2.0 (JSON or GLB) bytes; `buffer(uri)` supplies external buffers (the URI
/// as written: a relative reference or a `data:` URI) or says why it cannot.
/// Triangle-list primitives of every node of the default scene, with node transforms.
pub fn gltf(
    bytes: &[u8],
    buffer: impl FnMut(&str) -> Result<Vec<u8>, String>,
    scale: f32,
) -> Result<Loaded, LoadError> {
    let parse = |e: gltf::Error| gltf_error(e.to_string());
    check_glb_length(bytes)?;
    let unchecked = gltf::Gltf::from_slice_without_validation(bytes).map_err(parse)?;
    check_position_accessors(unchecked.document.as_json())?;
    let blob = unchecked.blob;
    let doc = gltf::Document::from_json(unchecked.document.into_json()).map_err(parse)?;
    let buffers = gltf_buffers(&doc, blob, buffer)?;
    let mut mesh = Mesh::default();
    let mut objects = Vec::new();
    let scene = doc.default_scene().or_else(|| doc.scenes().next());
    let mut stack: Vec<(gltf::Node, Mat4)> =
        scene.iter().flat_map(|s| s.nodes()).map(|n| (n, Mat4::IDENTITY)).collect();
    // glTF 2.0 §3.5.3: the nodes form disjoint trees, so each is reached once. A node
    // reached twice is a cycle (which would never end) or a shared subtree (which could
    // multiply the triangles exponentially): refused.
    let mut reached = vec![false; doc.nodes().len()];
    let mut triangles = 0usize;
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut reached[node.index()], true) {
            return Err(gltf_error(format!(
                "node {} is reached twice: glTF nodes form disjoint trees (no cycles, no shared children)",
                node.index()
            )));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(m) = node.mesh() {
            let tris = mesh_triangles(&m, world, &buffers)?;
            triangles += tris.len();
            if triangles > MAX_TRIANGLES {
                return Err(gltf_error(format!("more than {MAX_TRIANGLES} triangles")));
            }
            mesh.push_object(&tris, objects.len() as u32);
            objects.push(node.name().or(m.name()).unwrap_or("mesh").to_string());
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    finish(mesh, objects, scale)
}

/// A glTF file that cannot be read, with the reason.
fn gltf_error(message: String) -> LoadError {
    LoadError::Parse { format: "glTF", message }
}

/// Refuse a GLB header whose length is less than the header itself. glTF 2.0 §4.4.2: the
/// length counts the whole file, header included; gltf 1.4.1 subtracts the header's 12
/// bytes from it unchecked (found by the fuzzer).
fn check_glb_length(bytes: &[u8]) -> Result<(), LoadError> {
    if let Some(length) = bytes.strip_prefix(b"glTF").and_then(|rest| rest.get(4..8)) {
        let length = u32::from_le_bytes(length.try_into().expect("four bytes"));
        if length < 12 {
            return Err(gltf_error(format!(
                "the GLB header gives a length of {length} bytes, less than the header itself (12)"
            )));
        }
    }
    Ok(())
}

/// Refuse a primitive whose POSITION names an accessor past the end: gltf-json 1.4.1's
/// validation (mesh.rs, primitive_validate_hook) indexes the accessors with it before
/// checking it, and panics on one past the end (found by the glTF fuzzer).
fn check_position_accessors(json: &gltf::json::Root) -> Result<(), LoadError> {
    let positions = gltf::Semantic::Positions;
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position = prim.attributes.get(&gltf::json::validation::Checked::Valid(positions.clone()));
            if let Some(a) = position.filter(|a| a.value() >= json.accessors.len()) {
                return Err(gltf_error(format!(
                    "meshes[{m}].primitives[{p}].attributes.POSITION names accessor {}, but the file has {}",
                    a.value(),
                    json.accessors.len()
                )));
            }
        }
    }
    Ok(())
}

/// The bytes of every buffer of `doc` (at most [`MAX_BUFFERS`]): the GLB's BIN chunk
/// `blob`, or what `buffer(uri)` supplies; each at least as long as the file says.
fn gltf_buffers(
    doc: &gltf::Document,
    blob: Option<Vec<u8>>,
    mut buffer: impl FnMut(&str) -> Result<Vec<u8>, String>,
) -> Result<Vec<Vec<u8>>, LoadError> {
    if doc.buffers().len() > MAX_BUFFERS {
        return Err(gltf_error(format!(
            "{} buffers, more than the {MAX_BUFFERS} allowed",
            doc.buffers().len()
        )));
    }
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for b in doc.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => blob.clone().ok_or_else(|| LoadError::Buffer {
                uri: "(GLB BIN chunk)".into(),
                reason: "the file has no BIN chunk".into(),
            })?,
            gltf::buffer::Source::Uri(uri) => {
                buffer(uri).map_err(|reason| LoadError::Buffer { uri: uri.to_string(), reason })?
            }
        };
        if data.len() < b.length() {
            return Err(gltf_error(format!(
                "buffer {} holds {} bytes, the file says {}",
                b.index(),
                data.len(),
                b.length()
            )));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// The triangles of the triangle-list primitives of mesh `m`, placed by the node's
/// `world` transform; other primitive modes are skipped. Accessors are checked by
/// [`readable`] before they are read.
fn mesh_triangles(m: &gltf::Mesh, world: Mat4, buffers: &[Vec<u8>]) -> Result<Vec<[Vec3; 3]>, LoadError> {
    let mut tris = Vec::new();
    for prim in m.primitives() {
        if prim.mode() != gltf::mesh::Mode::Triangles {
            continue;
        }
        let bad = |reason: String| gltf_error(format!("mesh `{}`: {reason}", m.name().unwrap_or("?")));
        if let Some(a) = prim.get(&gltf::Semantic::Positions) {
            let vec3_f32 = a.dimensions() == Dimensions::Vec3 && a.data_type() == DataType::F32;
            readable(&a, "POSITION", vec3_f32, "VEC3 of FLOAT").map_err(bad)?;
        }
        if let Some(a) = prim.indices() {
            let unsigned = matches!(a.data_type(), DataType::U8 | DataType::U16 | DataType::U32);
            let scalar = a.dimensions() == Dimensions::Scalar && unsigned;
            readable(&a, "indices", scalar, "SCALAR of UNSIGNED_BYTE, _SHORT or _INT").map_err(bad)?;
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
        let Some(positions) = reader.read_positions() else { continue };
        let pos: Vec<Vec3> = positions.map(|p| world.transform_point3(Vec3::from(p))).collect();
        let idx: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..pos.len() as u32).collect(),
        };
        for t in idx.chunks_exact(3) {
            let get = |i: u32| pos.get(i as usize).copied();
            match (get(t[0]), get(t[1]), get(t[2])) {
                (Some(a), Some(b), Some(c)) => tris.push([a, b, c]),
                _ => {
                    return Err(gltf_error(format!(
                        "mesh `{}` has an index past its vertices",
                        m.name().unwrap_or("?")
                    )));
                }
            }
        }
    }
    Ok(tris)
}

/// Whether the `gltf` crate's accessor reader can read `a`: it trusts the element type,
/// stride, count and offsets written in the file (it asserts, overflows or reaches
/// `unreachable!` on bad ones), so they are checked here against glTF 2.0 §3.6.2
/// (accessors lie within their buffer views; a stride is at least the element size;
/// sparse counts between 1 and the accessor's count) and §3.7.2.1 (POSITION is VEC3
/// float; indices are unsigned scalars). A count is also capped at three vertices per
/// allowed triangle, since an accessor without a view is read as that many zeros.
fn readable(a: &gltf::Accessor, what: &str, type_ok: bool, expected: &str) -> Result<(), String> {
    let name = || format!("its {what} accessor ({})", a.index());
    if !type_ok {
        return Err(format!(
            "{} is {:?} of {:?}, glTF requires {expected}",
            name(),
            a.dimensions(),
            a.data_type()
        ));
    }
    let count = a.count();
    if count == 0 || count > 3 * MAX_TRIANGLES {
        return Err(format!("{} has count {count}, expected 1 to {}", name(), 3 * MAX_TRIANGLES));
    }
    // Elements `count` of `size` bytes from `offset` in `view`, `stride` apart, all inside it.
    let inside = |view: gltf::buffer::View, offset: usize, count: usize, size: usize| {
        let stride = view.stride().unwrap_or(size);
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|n| n.checked_add(size))
            .and_then(|n| n.checked_add(offset));
        stride >= size
            && view.offset().checked_add(view.length()).is_some()
            && end.is_some_and(|end| end <= view.length())
    };
    if a.view().is_some_and(|view| !inside(view, a.offset(), count, a.size())) {
        return Err(format!(
            "{} reaches past its buffer view or has a stride below its element size",
            name()
        ));
    }
    if let Some(sparse) = a.sparse() {
        let n = sparse.count();
        let (indices, values) = (sparse.indices(), sparse.values());
        if n == 0
            || n > count
            || !inside(indices.view(), indices.offset(), n, indices.index_type().size())
            || !inside(values.view(), values.offset(), n, a.size())
        {
            return Err(format!("{} has a sparse part that does not fit its count or buffer views", name()));
        }
    }
    Ok(())
}

/// Parse a DXF drawing's bytes: its 3DFACE entities (a fourth corner different from the
/// third makes a quad: two triangles), one object per layer, z-up turned to y-up. Needs
/// the `dxf` feature (on by default).
#[cfg(not(feature = "dxf"))]
pub fn dxf(_bytes: &[u8], _scale: f32) -> Result<Loaded, LoadError> {
    Err(LoadError::Parse {
        format: "DXF",
        message: "this build reads no DXF files (phenomena-snow was built without its `dxf` feature)".into(),
    })
}

/// Parse a DXF drawing's bytes: its 3DFACE entities (a fourth corner different from the
/// third makes a quad: two triangles), one object per layer, z-up turned to y-up. Needs
/// the `dxf` feature (on by default).
#[cfg(feature = "dxf")]
pub fn dxf(bytes: &[u8], scale: f32) -> Result<Loaded, LoadError> {
    let drawing = dxf::Drawing::load(&mut std::io::Cursor::new(bytes))
        .map_err(|e| LoadError::Parse { format: "DXF", message: e.to_string() })?;
    let mut layers: Vec<String> = Vec::new();
    let mut mesh = Mesh::default();
    let turn = |p: &dxf::Point| Vec3::new(p.x as f32, p.z as f32, -p.y as f32);
    for e in drawing.entities() {
        if let dxf::entities::EntityType::Face3D(f) = &e.specific {
            let layer = &e.common.layer;
            let o = match layers.iter().position(|l| l == layer) {
                Some(o) => o,
                None => {
                    layers.push(layer.clone());
                    layers.len() - 1
                }
            } as u32;
            let (a, b, c, d) = (
                turn(&f.first_corner),
                turn(&f.second_corner),
                turn(&f.third_corner),
                turn(&f.fourth_corner),
            );
            mesh.push_object(&[[a, b, c]], o);
            if d != c {
                mesh.push_object(&[[a, c, d]], o);
            }
        }
    }
    finish(mesh, layers, scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::{TriMesh, to_glb, to_obj};

    fn unit_quad() -> TriMesh {
        TriMesh {
            positions: vec![Vec3::ZERO, Vec3::Z, Vec3::new(1.0, 0.0, 1.0), Vec3::X],
            normals: vec![Vec3::Y; 4],
            indices: vec![0, 1, 2, 0, 2, 3],
        }
    }

    #[test]
    fn our_own_obj_and_glb_read_back() {
        let q = unit_quad();
        for loaded in [
            obj(to_obj(&q).as_bytes(), 2.0).unwrap(),
            gltf(&to_glb(&q), |_| Err("none".into()), 2.0).unwrap(),
        ] {
            assert_eq!(loaded.mesh.len(), 2);
            assert_eq!(loaded.cleaned, Cleaned::default());
            // Scaled by 2, facing up.
            assert_eq!(loaded.mesh.bounds().unwrap().1, Vec3::new(2.0, 0.0, 2.0));
            assert!(loaded.mesh.normal(0).y > 0.99);
        }
    }

    #[cfg(feature = "dxf")]
    #[test]
    fn a_dxf_3dface_is_turned_to_y_up() {
        // One square 3DFACE in the z = 1 plane (DXF is z-up), written by hand.
        let face = "0\nSECTION\n2\nENTITIES\n0\n3DFACE\n8\nroof\n10\n0.0\n20\n0.0\n30\n1.0\n11\n1.0\n21\n0.0\n31\n1.0\n12\n1.0\n22\n1.0\n32\n1.0\n13\n0.0\n23\n1.0\n33\n1.0\n0\nENDSEC\n0\nEOF\n";
        let loaded = dxf(face.as_bytes(), 1.0).unwrap();
        assert_eq!(loaded.mesh.len(), 2);
        assert_eq!(loaded.objects, vec!["roof".to_string()]);
        let (lo, hi) = loaded.mesh.bounds().unwrap();
        assert_eq!((lo.y, hi.y), (1.0, 1.0), "DXF z becomes height");
        assert_eq!((lo.z, hi.z), (-1.0, 0.0), "DXF y becomes -z");
        // Counter-clockwise seen from +z in DXF stays counter-clockwise seen from +y.
        assert!(loaded.mesh.normal(0).y > 0.99);
    }

    /// A node graph with a cycle would be walked for ever; a shared child multiplies
    /// the triangles: both refused (glTF nodes form disjoint trees).
    #[test]
    fn node_cycles_and_shared_children_are_refused() {
        let glb = to_glb_json_with_nodes(r#"[{"mesh":0,"children":[0]}]"#);
        let e = gltf(glb.as_bytes(), |_| Ok(tri_bytes()), 1.0).unwrap_err();
        assert!(e.to_string().contains("reached twice"), "{e}");
        let e = gltf(
            to_glb_json_with_nodes(r#"[{"children":[1,1]},{"mesh":0}]"#).as_bytes(),
            |_| Ok(tri_bytes()),
            1.0,
        )
        .unwrap_err();
        assert!(e.to_string().contains("node 1 is reached twice"), "{e}");
        assert!(
            gltf(
                to_glb_json_with_nodes(r#"[{"children":[1]},{"mesh":0}]"#).as_bytes(),
                |_| Ok(tri_bytes()),
                1.0
            )
            .is_ok()
        );
    }

    /// Found by the glTF fuzzer: a POSITION index past the accessors panicked inside
    /// gltf-json's own validation.
    #[test]
    fn a_position_past_the_accessors_is_refused() {
        let file = to_glb_json_with_nodes(r#"[{"mesh":0}]"#).replace(r#""POSITION":0"#, r#""POSITION":3"#);
        let e = gltf(file.as_bytes(), |_| Ok(tri_bytes()), 1.0).unwrap_err();
        assert!(
            e.to_string()
                .contains("meshes[0].primitives[0].attributes.POSITION names accessor 3, but the file has 1"),
            "{e}"
        );
        let e = gltf(b"glTF\x02\0\0\0\x08\0\0\0", |_| Ok(Vec::new()), 1.0).unwrap_err();
        assert!(e.to_string().contains("length of 8 bytes"), "{e}");
        // What the crate's reader trusts (found by the fuzzer: a debug assertion of its
        // element size fired; `unreachable!` for float indices).
        let base = to_glb_json_with_nodes(r#"[{"mesh":0}]"#);
        for (from, to, says) in [
            (
                r#""componentType":5126"#,
                r#""componentType":5121"#,
                "is Vec3 of U8, glTF requires VEC3 of FLOAT",
            ),
            (r#""count":3"#, r#""count":0"#, "has count 0"),
            (r#""count":3"#, r#""count":4"#, "reaches past its buffer view"),
            (
                r#""byteLength":36}],"buffers""#,
                r#""byteLength":36,"byteStride":4}],"buffers""#,
                "stride below",
            ),
            (r#""POSITION":0}"#, r#""POSITION":0},"indices":0"#, "its indices accessor (0) is Vec3 of F32"),
        ] {
            assert!(base.contains(from), "{from}");
            let e = gltf(base.replace(from, to).as_bytes(), |_| Ok(tri_bytes()), 1.0).unwrap_err();
            assert!(e.to_string().contains(says), "{to}: {e}");
        }
    }

    fn tri_bytes() -> Vec<u8> {
        [[0.0f32, 0.0, 0.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]]
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect()
    }

    /// One triangle mesh (buffer `b.bin`) under the nodes given, the scene's root node 0.
    fn to_glb_json_with_nodes(nodes: &str) -> String {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","max":[4,0,4],"min":[0,0,0]}}],"bufferViews":[{{"buffer":0,"byteLength":36}}],"buffers":[{{"uri":"b.bin","byteLength":36}}]}}"#
        )
    }

    /// Found by the OBJ fuzzer: a texture or normal index far past its list overflowed
    /// inside tobj; they are not used, so such files load by their positions.
    #[test]
    fn texture_and_normal_indices_are_not_read() {
        let file = b"v 0 0 0\nv 1 0 0\nv 0 0 1\nvt 0 0\nvn 0 1 0\nf 1/-9223372036854775807/-9223372036854775807 2/1/1 3//1\n";
        let loaded = obj(file, 1.0).unwrap();
        assert_eq!(loaded.mesh.triangles.len(), 1);
    }

    #[test]
    fn bad_files_say_what_is_wrong() {
        assert!(matches!(obj(b"v 0 0 0\nf 1 2 3\n", 1.0), Err(LoadError::Parse { format: "OBJ", .. })));
        assert!(matches!(obj(b"# nothing\n", 1.0), Err(LoadError::Empty { .. })));
        let e = obj(b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", 1.0).unwrap_err();
        assert_eq!(e, LoadError::Empty { non_finite: 0, degenerate: 1 });
        assert!(matches!(
            gltf(b"{not json", |_| Err("none".into()), 1.0),
            Err(LoadError::Parse { format: "glTF", .. })
        ));
        let external = r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"data.bin","byteLength":12}]}"#;
        assert_eq!(
            gltf(external.as_bytes(), |_| Err("not here".into()), 1.0).unwrap_err().to_string(),
            "the glTF buffer `data.bin` cannot be used: not here"
        );
        #[cfg(feature = "dxf")]
        assert!(matches!(
            dxf(b"0\nSECTION\n2\nENTITIES\n0\nENDSEC\n0\nEOF\n", 1.0),
            Err(LoadError::Empty { .. })
        ));
        assert!(matches!(
            dxf(b"garbage that is not a drawing", 1.0),
            Err(LoadError::Parse { .. }) | Err(LoadError::Empty { .. })
        ));
    }
}
