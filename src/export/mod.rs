//! Export: writing meshes as OBJ, glTF/GLB and PLY. (Being written: placeholder API.)

mod gltf;
mod obj;
mod ply;

use crate::import::MeshFormat;
use crate::mesh::Mesh;
use glam::DVec3;
use std::path::{Path, PathBuf};

/// A mesh to write, with optional per-vertex attributes.
pub struct MeshData<'a> {
    /// Positions.
    pub positions: &'a [DVec3],
    /// Triangles.
    pub triangles: &'a [[u32; 3]],
    /// Unit normals per vertex.
    pub normals: Option<&'a [DVec3]>,
    /// RGBA colours per vertex.
    pub colors: Option<&'a [[u8; 4]]>,
}

impl<'a> MeshData<'a> {
    /// Positions and triangles of a mesh.
    pub fn from_mesh(mesh: &'a Mesh) -> Self {
        MeshData {
            positions: mesh.positions(),
            triangles: mesh.faces(),
            normals: None,
            colors: None,
        }
    }
    /// Adds normals.
    pub fn with_normals(self, normals: &'a [DVec3]) -> Self {
        MeshData {
            normals: Some(normals),
            ..self
        }
    }
}

/// Why a mesh could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// Unsupported.
    #[error("{}: cannot write {format} files", path.display())]
    UnsupportedFormat {
        /// File.
        path: PathBuf,
        /// Format.
        format: String,
    },
}

/// Writes a mesh, choosing the format by extension.
pub fn write_mesh(path: &Path, _data: &MeshData<'_>) -> Result<(), ExportError> {
    let _ = MeshFormat::from_path(path);
    Err(ExportError::UnsupportedFormat {
        path: path.to_owned(),
        format: "any".into(),
    })
}
