//! Particle caches: a frame's particles as one binary little-endian PLY file
//! (Stanford PLY 1.0: a header naming `element vertex N` and its properties, then N
//! records of those properties in order), which Blender, Houdini and MeshLab import as
//! a point cloud (x, y, z; nx, ny, nz as normals where present; other properties as
//! attributes). Encoding only; [`crate::output`] writes the files.

/// One property column.
#[derive(Clone, Debug, PartialEq)]
pub enum Column {
    /// 32-bit float (PLY `float`).
    F32(Vec<f32>),
    /// 32-bit unsigned integer (PLY `uint`).
    U32(Vec<u32>),
}

impl Column {
    fn len(&self) -> usize {
        match self {
            Column::F32(v) => v.len(),
            Column::U32(v) => v.len(),
        }
    }

    fn ply_type(&self) -> &'static str {
        match self {
            Column::F32(_) => "float",
            Column::U32(_) => "uint",
        }
    }
}

/// A frame's particles: named columns of equal length.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCache {
    /// The properties in file order (`x`, `y`, `z` first).
    pub columns: Vec<(&'static str, Column)>,
    /// Comments for the header (units, the frame), one line each.
    pub comments: Vec<String>,
}

impl PointCache {
    /// Points.
    pub fn len(&self) -> usize {
        self.columns.first().map_or(0, |(_, c)| c.len())
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Add three float columns `names` from vectors.
    pub fn push_vec3(&mut self, names: [&'static str; 3], values: impl Iterator<Item = [f32; 3]> + Clone) {
        for (a, name) in names.into_iter().enumerate() {
            self.columns.push((name, Column::F32(values.clone().map(|v| v[a]).collect())));
        }
    }

    /// Add a float column.
    pub fn push_f32(&mut self, name: &'static str, values: Vec<f32>) {
        self.columns.push((name, Column::F32(values)));
    }

    /// Add an unsigned integer column.
    pub fn push_u32(&mut self, name: &'static str, values: Vec<u32>) {
        self.columns.push((name, Column::U32(values)));
    }

    /// The binary little-endian PLY file; `Err` when the columns differ in length.
    pub fn to_ply(&self) -> Result<Vec<u8>, String> {
        let n = self.len();
        if let Some((name, c)) = self.columns.iter().find(|(_, c)| c.len() != n) {
            return Err(format!("point cache column `{name}` has {} values, not {n}", c.len()));
        }
        let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
        for c in &self.comments {
            header.push_str("comment ");
            header.push_str(&c.replace(['\n', '\r'], " "));
            header.push('\n');
        }
        header.push_str(&format!("element vertex {n}\n"));
        for (name, c) in &self.columns {
            header.push_str(&format!("property {} {name}\n", c.ply_type()));
        }
        header.push_str("end_header\n");
        let mut out = Vec::with_capacity(header.len() + n * self.columns.len() * 4);
        out.extend_from_slice(header.as_bytes());
        for i in 0..n {
            for (_, c) in &self.columns {
                match c {
                    Column::F32(v) => out.extend_from_slice(&v[i].to_le_bytes()),
                    Column::U32(v) => out.extend_from_slice(&v[i].to_le_bytes()),
                }
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ply_layout() {
        let mut c = PointCache::default();
        c.push_vec3(["x", "y", "z"], [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]].into_iter());
        c.push_u32("id", vec![7, 8]);
        c.comments.push("units: metres".into());
        let bytes = c.to_ply().unwrap();
        let header = "ply\nformat binary_little_endian 1.0\ncomment units: metres\nelement vertex 2\n\
                      property float x\nproperty float y\nproperty float z\nproperty uint id\nend_header\n";
        assert_eq!(&bytes[..header.len()], header.as_bytes());
        let body = &bytes[header.len()..];
        assert_eq!(body.len(), 2 * 16);
        assert_eq!(f32::from_le_bytes(body[4..8].try_into().unwrap()), 2.0);
        assert_eq!(u32::from_le_bytes(body[12..16].try_into().unwrap()), 7);
        assert_eq!(f32::from_le_bytes(body[16..20].try_into().unwrap()), 4.0);
        c.push_f32("bad", vec![1.0]);
        assert!(c.to_ply().unwrap_err().contains("`bad`"));
    }
}
