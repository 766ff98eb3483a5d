//! Import: reading mesh files into a repaired [`Mesh`].
//!
//! Every file is hostile until proven otherwise. Each format's parser turns bytes into a
//! [`Soup`] (positions and triangles, polygons already fanned into triangles), checking every
//! count against [`ImportLimits`] and the bytes left before allocating, and reporting problems
//! as a [`ParseError`] with the line or byte offset where they occur. [`repair`] then welds
//! split vertices, drops degenerate, duplicate and unreferenced elements, orients faces
//! consistently, and says what it did in a [`RepairReport`].
//!
//! The single entry point is [`read_mesh`]; [`read_mesh_bytes`] does the same from memory.

mod gltf;
mod obj;
mod off;
mod ply;
pub mod repair;
mod stl;

pub use repair::{RepairReport, Weld};

use crate::mesh::Mesh;
use glam::DVec3;
use serde::Serialize;
use std::fmt;
use std::path::{Path, PathBuf};

/// The mesh file formats ellip reads (and, but for STL and OFF, writes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MeshFormat {
    /// Wavefront OBJ.
    Obj,
    /// glTF 2.0, JSON with external or embedded buffers.
    Gltf,
    /// glTF 2.0, binary container.
    Glb,
    /// Stanford PLY, ASCII or binary.
    Ply,
    /// STL, ASCII or binary.
    Stl,
    /// Object File Format.
    Off,
}

impl MeshFormat {
    /// The format named by a file's extension (case-insensitive).
    pub fn from_path(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "obj" => MeshFormat::Obj,
            "gltf" => MeshFormat::Gltf,
            "glb" => MeshFormat::Glb,
            "ply" => MeshFormat::Ply,
            "stl" => MeshFormat::Stl,
            "off" => MeshFormat::Off,
            _ => return None,
        })
    }

    /// The format announced by a file's first bytes, where that is cheap and unambiguous.
    /// OBJ and ASCII STL have no magic number and are not sniffed (but `solid` is).
    pub fn sniff(bytes: &[u8]) -> Option<MeshFormat> {
        if bytes.starts_with(b"glTF") {
            Some(MeshFormat::Glb)
        } else if bytes.starts_with(b"ply") {
            Some(MeshFormat::Ply)
        } else if is_off_keyword(bytes) {
            Some(MeshFormat::Off)
        } else if bytes.starts_with(b"solid") {
            Some(MeshFormat::Stl)
        } else {
            None
        }
    }

    /// Lower-case name, as used in messages and `--json` output.
    pub fn name(self) -> &'static str {
        match self {
            MeshFormat::Obj => "obj",
            MeshFormat::Gltf => "gltf",
            MeshFormat::Glb => "glb",
            MeshFormat::Ply => "ply",
            MeshFormat::Stl => "stl",
            MeshFormat::Off => "off",
        }
    }
}

impl fmt::Display for MeshFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Caps on what a file may make the importer allocate. Counts declared in a file are checked
/// against these and against the bytes actually present before any allocation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImportLimits {
    /// Largest file read, in bytes (default 4 GiB).
    pub max_file_bytes: u64,
    /// Most vertices (default 2²⁷ ≈ 134 million).
    pub max_vertices: u64,
    /// Most triangles after triangulating polygons (default 2²⁷).
    pub max_faces: u64,
}

impl Default for ImportLimits {
    fn default() -> Self {
        ImportLimits {
            max_file_bytes: 4 << 30,
            max_vertices: 1 << 27,
            max_faces: 1 << 27,
        }
    }
}

/// How to read and repair a file.
#[derive(Debug, Clone, Default)]
pub struct ImportOptions {
    /// The format; `None` chooses by extension, then by content.
    pub format: Option<MeshFormat>,
    /// How split vertices are joined (default: exactly equal positions).
    pub weld: Weld,
    /// Keep the file's face orientation instead of making it consistent and outward.
    pub keep_orientation: bool,
    /// Allocation caps.
    pub limits: ImportLimits,
}

/// Where in a file a problem is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Location {
    /// 1-based line number, for text formats.
    Line(u64),
    /// 0-based byte offset, for binary formats.
    Byte(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(n) => write!(f, "line {n}"),
            Location::Byte(n) => write!(f, "byte {n}"),
        }
    }
}

/// What is wrong with a file's content. Malformed input and valid-but-unsupported input are
/// kept apart: [`Problem::Unsupported`] is the only variant for files that are well formed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Problem {
    /// The file holds no bytes, or nothing but whitespace and comments.
    #[error("the file is empty")]
    Empty,
    /// The content is not this format at all.
    #[error("not a {expected} file")]
    NotThisFormat {
        /// The format that was expected.
        expected: &'static str,
    },
    /// A header is malformed.
    #[error("bad header: {reason}")]
    BadHeader {
        /// What is wrong.
        reason: String,
    },
    /// A token could not be read as what the grammar requires there.
    #[error("expected {expected}, found {found:?}")]
    Syntax {
        /// What was expected (e.g. "a number").
        expected: &'static str,
        /// The offending text, shortened to at most 40 characters.
        found: String,
    },
    /// The data ends before what the header or structure promises.
    #[error("truncated: {needed} bytes needed, {available} present")]
    Truncated {
        /// Bytes required from the start of the element being read.
        needed: u64,
        /// Bytes actually present from there.
        available: u64,
    },
    /// A declared count does not match what the file contains.
    #[error("{what}: {declared} declared, {found} found")]
    CountMismatch {
        /// What is being counted.
        what: &'static str,
        /// Count from the header.
        declared: u64,
        /// Count actually present.
        found: u64,
    },
    /// A coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteCoordinate {
        /// 0-based vertex number.
        vertex: u64,
    },
    /// A face refers to a vertex that does not exist.
    #[error("face index {index} is out of range (there are {vertex_count} vertices)")]
    IndexOutOfRange {
        /// The index as written in the file (OBJ: 1-based or negative).
        index: i64,
        /// Number of vertices.
        vertex_count: u64,
    },
    /// A face with fewer than three vertices.
    #[error("a face has {vertices} vertices; at least 3 are needed")]
    FaceTooSmall {
        /// How many it has.
        vertices: u64,
    },
    /// A count exceeds an [`ImportLimits`] cap.
    #[error("{what}: {requested} exceeds the limit of {max}")]
    LimitsExceeded {
        /// What is being counted.
        what: &'static str,
        /// What the file asks for.
        requested: u64,
        /// The cap.
        max: u64,
    },
    /// Well formed, but uses something ellip does not read.
    #[error("unsupported: {what}")]
    Unsupported {
        /// What it is.
        what: String,
    },
    /// A glTF document that the glTF reader rejects.
    #[error("invalid glTF: {message}")]
    Gltf {
        /// The reader's message.
        message: String,
    },
}

/// A [`Problem`] and where it is, as returned by each format's parser.
#[derive(Debug, Clone, PartialEq)]
pub struct ParseError {
    /// Line or byte offset, where it applies.
    pub at: Option<Location>,
    /// What is wrong.
    pub problem: Problem,
}

impl ParseError {
    /// A problem at a known place.
    pub fn at(at: Location, problem: Problem) -> Self {
        ParseError {
            at: Some(at),
            problem,
        }
    }

    /// A problem that belongs to the file as a whole.
    pub fn whole(problem: Problem) -> Self {
        ParseError { at: None, problem }
    }
}

/// Why a mesh file could not be imported. Its `Display` is one line naming the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// The file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// Neither the extension nor the content says which format this is.
    #[error("{}: unknown mesh format (expected .obj, .gltf, .glb, .ply, .stl or .off)", path.display())]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The content is malformed, unsupported or over a limit.
    #[error("{}: {format}{}: {problem}", path.display(), at.map(|l| format!(", {l}")).unwrap_or_default())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// The format it was read as.
        format: MeshFormat,
        /// Line or byte offset, where it applies.
        at: Option<Location>,
        /// What is wrong.
        problem: Problem,
    },
    /// The file is well formed but holds no usable triangle.
    #[error("{}: no triangles left after removing {removed} degenerate or duplicate faces", path.display())]
    NoTriangles {
        /// The file.
        path: PathBuf,
        /// How many faces were removed.
        removed: u64,
    },
}

/// Positions and triangles as a parser reads them, before any repair.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Soup {
    /// Vertex positions, finite.
    pub positions: Vec<DVec3>,
    /// Triangles; every index is below `positions.len()`.
    pub triangles: Vec<[u32; 3]>,
    /// Polygons with more than three vertices that were fanned into triangles.
    pub triangulated_polygons: u64,
    /// Things skipped or ignored that the user should hear about (e.g. glTF line primitives).
    pub warnings: Vec<String>,
}

/// A mesh read from a file, and what was done to it on the way in.
#[derive(Debug, Clone)]
pub struct Imported {
    /// The repaired mesh.
    pub mesh: Mesh,
    /// The format it was read as.
    pub format: MeshFormat,
    /// What the repair did.
    pub repairs: RepairReport,
    /// Warnings from the parser.
    pub warnings: Vec<String>,
}

/// Reads a mesh file: chooses the format, parses it, and repairs the result.
pub fn read_mesh(path: &Path, options: &ImportOptions) -> Result<Imported, ImportError> {
    let io_error = |source| ImportError::Io {
        path: path.to_owned(),
        source,
    };
    let len = std::fs::metadata(path).map_err(io_error)?.len();
    if len > options.limits.max_file_bytes {
        return Err(ImportError::Malformed {
            path: path.to_owned(),
            format: options
                .format
                .or_else(|| MeshFormat::from_path(path))
                .unwrap_or(MeshFormat::Obj),
            at: None,
            problem: Problem::LimitsExceeded {
                what: "file size in bytes",
                requested: len,
                max: options.limits.max_file_bytes,
            },
        });
    }
    let bytes = std::fs::read(path).map_err(io_error)?;
    read_mesh_bytes(&bytes, path, options)
}

/// Imports a mesh from bytes already in memory. `path` names the file in messages, chooses
/// the format by extension, and locates external glTF buffers.
pub fn read_mesh_bytes(
    bytes: &[u8],
    path: &Path,
    options: &ImportOptions,
) -> Result<Imported, ImportError> {
    let format = options
        .format
        .or_else(|| MeshFormat::from_path(path))
        .or_else(|| MeshFormat::sniff(bytes))
        .ok_or_else(|| ImportError::UnknownFormat {
            path: path.to_owned(),
        })?;
    let limits = &options.limits;
    let parsed = match format {
        MeshFormat::Obj => obj::parse(bytes, limits),
        MeshFormat::Gltf | MeshFormat::Glb => gltf::parse(bytes, path.parent(), limits),
        MeshFormat::Ply => ply::parse(bytes, limits),
        MeshFormat::Stl => stl::parse(bytes, limits),
        MeshFormat::Off => off::parse(bytes, limits),
    };
    let soup = parsed.map_err(|e| ImportError::Malformed {
        path: path.to_owned(),
        format,
        at: e.at,
        problem: e.problem,
    })?;
    let warnings = soup.warnings.clone();
    let (mesh, repairs) = repair::repair(soup, options).map_err(|removed| match removed {
        repair::RepairFailure::NoTriangles { removed } => ImportError::NoTriangles {
            path: path.to_owned(),
            removed,
        },
    })?;
    Ok(Imported {
        mesh,
        format,
        repairs,
        warnings,
    })
}

/// `[ST][C][N][4][n]OFF` as the first token: the OFF header keyword and its variants.
fn is_off_keyword(bytes: &[u8]) -> bool {
    let token_len = bytes
        .iter()
        .take(8)
        .position(|b| b.is_ascii_whitespace())
        .unwrap_or(bytes.len().min(8));
    let token = &bytes[..token_len];
    token.ends_with(b"OFF")
        && token[..token.len() - 3]
            .iter()
            .all(|b| b"STCN4n".contains(b))
}

/// A whitespace-free word of a text format read as a number; `None` when it is not one.
pub(crate) fn parse_word<T: std::str::FromStr>(word: &[u8]) -> Option<T> {
    std::str::from_utf8(word).ok()?.parse().ok()
}

/// Shortens a token for an error message.
pub(crate) fn excerpt(bytes: &[u8]) -> String {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(40)]);
    text.into_owned()
}

/// Checks a declared count against a cap.
pub(crate) fn check_limit(what: &'static str, requested: u64, max: u64) -> Result<(), Problem> {
    if requested > max {
        Err(Problem::LimitsExceeded {
            what,
            requested,
            max,
        })
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sniffs_formats_by_their_first_bytes() {
        assert_eq!(MeshFormat::sniff(b"glTF\x02\0\0\0"), Some(MeshFormat::Glb));
        assert_eq!(MeshFormat::sniff(b"ply\nformat"), Some(MeshFormat::Ply));
        for off in [
            &b"OFF\n"[..],
            b"COFF 1 2 3",
            b"NOFF\n",
            b"STCNOFF\n",
            b"OFF",
        ] {
            assert_eq!(MeshFormat::sniff(off), Some(MeshFormat::Off), "{off:?}");
        }
        assert_eq!(MeshFormat::sniff(b"solid x"), Some(MeshFormat::Stl));
        assert_eq!(MeshFormat::sniff(b"OFFSET 1"), None);
        assert_eq!(MeshFormat::sniff(b"v 1 2 3"), None);
        assert_eq!(MeshFormat::sniff(b""), None);
    }
}
