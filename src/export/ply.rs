//! PLY writer: `binary_little_endian 1.0` with `float` positions, optional `float` normals
//! and `uchar` RGBA colours, and faces as `property list uchar int vertex_indices` — the
//! layout most readers (Blender, MeshLab, Open3D) expect.

use super::{invalid, Checked, ExportError};
use std::io::{self, Write};

/// PLY faces hold `int` (signed 32-bit) indices: checks that every index fits.
pub(super) fn check_limits(data: &Checked<'_>) -> Result<(), ExportError> {
    let n = data.positions.len();
    if i32::try_from(n).is_err() {
        return Err(invalid(
            "positions",
            format!(
                "{n} vertices; PLY's int indices address at most {}",
                i32::MAX
            ),
        ));
    }
    Ok(())
}

/// Writes `data` as binary PLY. [`check_limits`] must have passed.
pub(super) fn write(w: &mut dyn Write, data: &Checked<'_>) -> io::Result<()> {
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment ellip\n");
    header += &format!("element vertex {}\n", data.positions.len());
    header += "property float x\nproperty float y\nproperty float z\n";
    if data.normals.is_some() {
        header += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    if data.colors.is_some() {
        header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
        header += "property uchar alpha\n";
    }
    header += &format!("element face {}\n", data.triangles.len());
    header += "property list uchar int vertex_indices\nend_header\n";
    w.write_all(header.as_bytes())?;

    let mut record = Vec::with_capacity(28);
    for (v, p) in data.positions.iter().enumerate() {
        record.clear();
        for x in p.as_vec3().to_array() {
            record.extend_from_slice(&x.to_le_bytes());
        }
        if let Some(n) = data.normals.and_then(|normals| normals.get(v)) {
            for x in n.as_vec3().to_array() {
                record.extend_from_slice(&x.to_le_bytes());
            }
        }
        if let Some(c) = data.colors.and_then(|colors| colors.get(v)) {
            record.extend_from_slice(c);
        }
        w.write_all(&record)?;
    }
    for triangle in data.triangles {
        record.clear();
        record.push(3);
        for &i in triangle {
            // Below the vertex count, which check_limits bounded by i32::MAX.
            let i = i32::try_from(i).map_err(|_| io::Error::other("vertex index exceeds i32"))?;
            record.extend_from_slice(&i.to_le_bytes());
        }
        w.write_all(&record)?;
    }
    Ok(())
}
