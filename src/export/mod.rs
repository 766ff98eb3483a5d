//! Export: writing meshes as OBJ, PLY, glTF and GLB.
//!
//! A [`MeshData`] borrows positions, triangles and optional per-vertex normals and colours.
//! [`write_mesh`] chooses the format by the file's extension and [`encode_mesh`] produces the
//! bytes of a single-file format in memory (for standard output). Both check the data first
//! (attribute lengths, index range, finite values that fit in `f32`) and return
//! [`ExportError::InvalidData`] rather than write a broken file.
//!
//! Every file is written atomically (a temporary file renamed over the destination), so an
//! interrupted export never leaves a half-written file. A `.gltf` is written as two files,
//! `<stem>.bin` first and then `<stem>.gltf`, which refers to the buffer by a relative URI.
//!
//! What each format holds:
//!
//! | format | positions | normals | colours | notes |
//! |---|---|---|---|---|
//! | OBJ | `v`, shortest `f32` text | `vn` if given | no | byte-deterministic text |
//! | PLY | `float` | `float` if given | `uchar` RGBA if given | `binary_little_endian 1.0` |
//! | glTF/GLB | `FLOAT` `VEC3` | always (computed if not given) | `COLOR_0` if given | glTF 2.0 |
//!
//! glTF requires unit normals, so the glTF writers renormalise them in `f32`; when no normals
//! are given they write the angle-weighted vertex normals of [`Mesh::vertex_normals`]. OBJ and
//! PLY write normals only when given, as given.

mod gltf;
mod obj;
mod ply;

use crate::import::MeshFormat;
use crate::mesh::{Mesh, MAX_ELEMENTS};
use glam::{DVec3, Vec3};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// A mesh to export: positions, triangles and optional per-vertex attributes, all borrowed.
///
/// Build it with [`MeshData::from_mesh`] (or directly from slices) and add attributes with
/// [`MeshData::with_normals`] and [`MeshData::with_colors`]. Attribute slices hold one entry
/// per position. Nothing is checked until it is written.
#[derive(Debug, Clone, Copy)]
pub struct MeshData<'a> {
    /// Vertex positions.
    pub positions: &'a [DVec3],
    /// Triangles as indices into `positions`, counter-clockwise seen from outside.
    pub triangles: &'a [[u32; 3]],
    /// Per-vertex normals; need not be unit length, but must be finite and non-zero both in
    /// `f64` and once converted to `f32`.
    pub normals: Option<&'a [DVec3]>,
    /// Per-vertex colours, RGBA with 8 bits per channel (not written to OBJ).
    pub colors: Option<&'a [[u8; 4]]>,
}

impl<'a> MeshData<'a> {
    /// The positions and triangles of `mesh`, without normals or colours.
    pub fn from_mesh(mesh: &'a Mesh) -> Self {
        MeshData {
            positions: mesh.positions(),
            triangles: mesh.faces(),
            normals: None,
            colors: None,
        }
    }

    /// The same data with per-vertex normals.
    pub fn with_normals(self, normals: &'a [DVec3]) -> Self {
        MeshData {
            normals: Some(normals),
            ..self
        }
    }

    /// The same data with per-vertex RGBA colours.
    pub fn with_colors(self, colors: &'a [[u8; 4]]) -> Self {
        MeshData {
            colors: Some(colors),
            ..self
        }
    }
}

/// Why a mesh could not be exported. Its `Display` is one line.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// A file could not be written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: io::Error,
    },
    /// The format or extension is not one ellip writes.
    #[error("{}cannot write {format}: ellip writes .obj, .ply, .gltf and .glb",
        path.as_ref().map(|p| format!("{}: ", p.display())).unwrap_or_default())]
    UnsupportedFormat {
        /// The file, when writing to one.
        path: Option<PathBuf>,
        /// The format asked for (`stl`, `off`) or, for an unknown extension, a description
        /// such as `extension ".xyz"` or `a file without extension`.
        format: String,
    },
    /// The mesh data is inconsistent or cannot be represented in the format.
    #[error("invalid mesh data: {what}: {detail}")]
    InvalidData {
        /// Which part of the data is wrong (e.g. `"normals"`, `"triangle index"`).
        what: &'static str,
        /// What is wrong, with the expected and actual values.
        detail: String,
    },
}

/// Writes `data` to `path` in the format named by its extension (`.obj`, `.ply`, `.glb`,
/// `.gltf`; case-insensitive), atomically. A `.gltf` also writes its buffer to `<stem>.bin`
/// beside it, replacing any file of that name.
pub fn write_mesh(path: &Path, data: &MeshData<'_>) -> Result<(), ExportError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| ExportError::UnsupportedFormat {
        path: Some(path.to_owned()),
        format: match path.extension() {
            Some(ext) => format!("extension {:?}", ext.to_string_lossy()),
            None => "a file without extension".to_owned(),
        },
    })?;
    let unsupported = || ExportError::UnsupportedFormat {
        path: Some(path.to_owned()),
        format: format.name().to_owned(),
    };
    let io_error = |path: &Path| {
        let path = path.to_owned();
        move |source| ExportError::Io { path, source }
    };
    match format {
        MeshFormat::Obj => {
            let checked = check(data)?;
            write_file(path, |w| obj::write(w, &checked)).map_err(io_error(path))
        }
        MeshFormat::Ply => {
            let checked = check(data)?;
            ply::check_limits(&checked)?;
            write_file(path, |w| ply::write(w, &checked)).map_err(io_error(path))
        }
        MeshFormat::Glb => {
            let bytes = gltf::encode_glb(&check(data)?)?;
            write_file(path, |w| w.write_all(&bytes)).map_err(io_error(path))
        }
        MeshFormat::Gltf => {
            let checked = check(data)?;
            let bin_path = gltf::buffer_path(path).ok_or_else(unsupported)?;
            let bin_name = bin_path
                .file_name()
                .ok_or_else(unsupported)?
                .as_encoded_bytes();
            let (json, bin) = gltf::encode_separate(&checked, &gltf::encode_uri(bin_name))?;
            write_file(&bin_path, |w| w.write_all(&bin)).map_err(io_error(&bin_path))?;
            write_file(path, |w| w.write_all(&json)).map_err(io_error(path))
        }
        MeshFormat::Stl | MeshFormat::Off => Err(unsupported()),
    }
}

/// Encodes `data` in a single-file format, for writing to standard output: OBJ, PLY, GLB,
/// or glTF with its buffer embedded as a base64 `data:` URI. STL and OFF are
/// [`ExportError::UnsupportedFormat`].
pub fn encode_mesh(format: MeshFormat, data: &MeshData<'_>) -> Result<Vec<u8>, ExportError> {
    let checked = check(data)?;
    let in_memory = |e: io::Error| ExportError::Io {
        path: PathBuf::from("<memory>"),
        source: e,
    };
    match format {
        MeshFormat::Obj => {
            let mut out = Vec::new();
            obj::write(&mut out, &checked).map_err(in_memory)?;
            Ok(out)
        }
        MeshFormat::Ply => {
            ply::check_limits(&checked)?;
            let mut out = Vec::new();
            ply::write(&mut out, &checked).map_err(in_memory)?;
            Ok(out)
        }
        MeshFormat::Glb => gltf::encode_glb(&checked),
        MeshFormat::Gltf => gltf::encode_embedded(&checked),
        MeshFormat::Stl | MeshFormat::Off => Err(ExportError::UnsupportedFormat {
            path: None,
            format: format.name().to_owned(),
        }),
    }
}

/// Writes a file through [`crate::atomic::write_atomic`].
fn write_file(path: &Path, fill: impl FnOnce(&mut dyn Write) -> io::Result<()>) -> io::Result<()> {
    crate::atomic::write_atomic(path, fill)
}

/// [`MeshData`] that has passed [`check`]: lengths agree, indices are in range, and every
/// position and normal converts to finite `f32` values (normals also non-zero).
pub(crate) struct Checked<'a> {
    pub(crate) positions: &'a [DVec3],
    pub(crate) triangles: &'a [[u32; 3]],
    pub(crate) normals: Option<&'a [DVec3]>,
    pub(crate) colors: Option<&'a [[u8; 4]]>,
}

/// Checks `data` for everything a writer relies on.
fn check<'a>(data: &MeshData<'a>) -> Result<Checked<'a>, ExportError> {
    let n = data.positions.len();
    if n > MAX_ELEMENTS {
        return Err(invalid(
            "positions",
            format!("{n} vertices, more than the {MAX_ELEMENTS} that 32-bit indices address"),
        ));
    }
    if data.triangles.len() > MAX_ELEMENTS {
        return Err(invalid(
            "triangles",
            format!(
                "{} triangles, more than {MAX_ELEMENTS}",
                data.triangles.len()
            ),
        ));
    }
    if data.triangles.is_empty() {
        return Err(invalid("triangles", "there are none".to_owned()));
    }
    if let Some(normals) = data.normals {
        if normals.len() != n {
            return Err(invalid(
                "normals",
                format!("{} given for {n} vertices", normals.len()),
            ));
        }
    }
    if let Some(colors) = data.colors {
        if colors.len() != n {
            return Err(invalid(
                "colors",
                format!("{} given for {n} vertices", colors.len()),
            ));
        }
    }
    for (face, triangle) in data.triangles.iter().enumerate() {
        if let Some(&index) = triangle.iter().find(|&&i| i as usize >= n) {
            return Err(invalid(
                "triangle index",
                format!("triangle {face} refers to vertex {index}, but there are {n} vertices"),
            ));
        }
    }
    for (vertex, p) in data.positions.iter().enumerate() {
        if !p.is_finite() || !p.as_vec3().is_finite() {
            return Err(invalid(
                "position",
                format!("vertex {vertex} is {p}, which is not a finite 32-bit float vector"),
            ));
        }
    }
    if let Some(normals) = data.normals {
        for (vertex, n) in normals.iter().enumerate() {
            let single = n.as_vec3();
            if n.try_normalize().is_none() || !single.is_finite() || single == Vec3::ZERO {
                return Err(invalid(
                    "normal",
                    format!("vertex {vertex} has normal {n}; normals must be finite and non-zero"),
                ));
            }
        }
    }
    Ok(Checked {
        positions: data.positions,
        triangles: data.triangles,
        normals: data.normals,
        colors: data.colors,
    })
}

/// An [`ExportError::InvalidData`].
fn invalid(what: &'static str, detail: String) -> ExportError {
    ExportError::InvalidData { what, detail }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uri_encoding_keeps_unreserved_and_escapes_the_rest() {
        assert_eq!(gltf::encode_uri(b"a-b_c.d~e.bin"), "a-b_c.d~e.bin");
        assert_eq!(
            gltf::encode_uri("my mesh é%.bin".as_bytes()),
            "my%20mesh%20%C3%A9%25.bin"
        );
    }
}
