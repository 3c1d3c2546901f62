//! Scene meshes from files' bytes: Wavefront OBJ (tobj), glTF 2.0 / GLB (gltf) and DXF
//! 3DFACE entities (dxf, the paper's format). The caller reads the files (libraries do
//! no IO); each object, glTF mesh node or DXF layer becomes one object of the [`Mesh`].
//!
//! OBJ and glTF are y-up; DXF drawings are z-up and are turned so that their z becomes
//! our y (x stays, y becomes -z), keeping the handedness.

use glam::{Mat4, Vec3};

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
    let (models, _) = tobj::load_obj_buf(&mut std::io::Cursor::new(bytes), &options, |_| {
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
    mut buffer: impl FnMut(&str) -> Result<Vec<u8>, String>,
    scale: f32,
) -> Result<Loaded, LoadError> {
    let parse = |e: gltf::Error| LoadError::Parse { format: "glTF", message: e.to_string() };
    let doc = gltf::Gltf::from_slice(bytes).map_err(parse)?;
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for b in doc.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => doc.blob.clone().ok_or_else(|| LoadError::Buffer {
                uri: "(GLB BIN chunk)".into(),
                reason: "the file has no BIN chunk".into(),
            })?,
            gltf::buffer::Source::Uri(uri) => {
                buffer(uri).map_err(|reason| LoadError::Buffer { uri: uri.to_string(), reason })?
            }
        };
        if data.len() < b.length() {
            return Err(LoadError::Parse {
                format: "glTF",
                message: format!(
                    "buffer {} holds {} bytes, the file says {}",
                    b.index(),
                    data.len(),
                    b.length()
                ),
            });
        }
        buffers.push(data);
    }
    let mut mesh = Mesh::default();
    let mut objects = Vec::new();
    let scene = doc.default_scene().or_else(|| doc.scenes().next());
    let mut stack: Vec<(gltf::Node, Mat4)> =
        scene.iter().flat_map(|s| s.nodes()).map(|n| (n, Mat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(m) = node.mesh() {
            let mut tris = Vec::new();
            for prim in m.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    continue;
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
                            return Err(LoadError::Parse {
                                format: "glTF",
                                message: format!(
                                    "mesh `{}` has an index past its vertices",
                                    m.name().unwrap_or("?")
                                ),
                            });
                        }
                    }
                }
            }
            mesh.push_object(&tris, objects.len() as u32);
            objects.push(node.name().or(m.name()).unwrap_or("mesh").to_string());
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    finish(mesh, objects, scale)
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
