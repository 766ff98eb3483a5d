//! glTF 2.0 reader, for both the JSON form (`.gltf`) and the binary container (`.glb`).
//!
//! The `gltf` crate parses and validates the JSON document (every index it holds refers to an
//! existing object). Everything else is done here, because the crate's own loaders trust the
//! file: the GLB container is split by [`split_glb`] (the crate's splitter subtracts without
//! checking a declared length), buffers are resolved by [`Reader::buffer`] (GLB `BIN` chunk,
//! base64 `data:` URIs, or relative files under the glTF's folder, nothing else), and every
//! accessor is bounds-checked by [`Reader::accessor_bytes`] before a byte of it is read.
//!
//! The mesh is what the default scene shows (the `scene` property, else the first scene):
//! every triangle primitive of every mesh instance, transformed by its node's world transform
//! (composed in f64, parent × child), with the winding reversed under mirroring transforms.
//! A file without scenes contributes each mesh once, untransformed. Triangle strips and fans
//! are converted to triangles; points and lines are skipped with a warning.

use super::{check_limit, ImportLimits, Location, ParseError, Problem, Soup};
use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
use base64::Engine as _;
use glam::{DMat4, DQuat, DVec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::buffer::Source;
use gltf::mesh::Mode;
use gltf::{Accessor, Document, Semantic};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Component, Path};

/// Parses a glTF or GLB file; `base` is the folder external buffers are relative to.
pub(crate) fn parse(
    bytes: &[u8],
    base: Option<&Path>,
    limits: &ImportLimits,
) -> Result<Soup, ParseError> {
    let (json, bin) = if bytes.starts_with(b"glTF") {
        let glb = split_glb(bytes)?;
        (glb.json, glb.bin)
    } else {
        // A byte-order mark is allowed to be ignored ("JSON encoding"); serde_json rejects it.
        (bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes), None)
    };
    if json.iter().all(u8::is_ascii_whitespace) {
        return Err(ParseError::whole(Problem::Empty));
    }
    let root = gltf::json::Root::from_slice(json).map_err(|e| {
        if let Some(problem) = unsupported_kind(json) {
            return ParseError::whole(problem);
        }
        let problem = Problem::Gltf {
            message: e.to_string(),
        };
        // Lines mean something in a .gltf; in a GLB they would count within the JSON chunk.
        match e.line() {
            line if line > 0 && !bytes.starts_with(b"glTF") => {
                ParseError::at(Location::Line(line as u64), problem)
            }
            _ => ParseError::whole(problem),
        }
    })?;
    check_position_indices(&root)?;
    let document = Document::from_json(root).map_err(|e| {
        ParseError::whole(unsupported_kind(json).unwrap_or_else(|| describe_gltf_error(e)))
    })?;
    let mut reader = Reader {
        document: &document,
        bin,
        base,
        limits,
        buffers: vec![None; document.buffers().len()],
        soup: Soup::default(),
        skipped: BTreeMap::new(),
    };
    for (mesh, transform) in find_mesh_instances(&document)? {
        reader.read_instance(mesh, transform)?;
    }
    let mut soup = reader.soup;
    for (what, n) in reader.skipped {
        soup.warnings.push(format!("skipped {n} {what}"));
    }
    Ok(soup)
}

/// The chunks of a GLB file.
struct Glb<'a> {
    json: &'a [u8],
    bin: Option<Bin<'a>>,
}

/// The `BIN` chunk of a GLB file and where it starts.
#[derive(Clone, Copy)]
struct Bin<'a> {
    data: &'a [u8],
    offset: u64,
}

/// Splits a GLB container (glTF 2.0, "Binary glTF Layout") into its JSON and first `BIN` chunk, checking the
/// header and every chunk length against the bytes present.
fn split_glb(bytes: &[u8]) -> Result<Glb<'_>, ParseError> {
    let available = bytes.len() as u64;
    let read_u32 = |at: u64| -> Option<u32> {
        let at = usize::try_from(at).ok()?;
        let word = bytes.get(at..at.checked_add(4)?)?;
        Some(u32::from_le_bytes(word.try_into().ok()?))
    };
    let (Some(version), Some(length)) = (read_u32(4), read_u32(8)) else {
        return Err(ParseError::at(
            Location::Byte(0),
            Problem::Truncated {
                needed: 12,
                available,
            },
        ));
    };
    if version != 2 {
        return Err(ParseError::at(
            Location::Byte(4),
            Problem::Unsupported {
                what: format!("GLB container version {version}"),
            },
        ));
    }
    let length = u64::from(length);
    if length < 12 {
        return Err(ParseError::at(
            Location::Byte(8),
            Problem::BadHeader {
                reason: format!("declared length {length} is shorter than the header"),
            },
        ));
    }
    if length > available {
        return Err(ParseError::at(
            Location::Byte(0),
            Problem::Truncated {
                needed: length,
                available,
            },
        ));
    }
    let mut json = None;
    let mut bin = None;
    let mut offset = 12u64;
    while offset < length {
        let truncated = |needed: u64| {
            ParseError::at(
                Location::Byte(offset),
                Problem::Truncated {
                    needed,
                    available: length - offset,
                },
            )
        };
        if length - offset < 8 {
            return Err(truncated(8));
        }
        let (Some(chunk_length), Some(kind)) = (read_u32(offset), read_u32(offset + 4)) else {
            return Err(truncated(8));
        };
        let end = offset + 8 + u64::from(chunk_length);
        if end > length {
            return Err(truncated(8 + u64::from(chunk_length)));
        }
        let data = usize::try_from(offset + 8)
            .ok()
            .zip(usize::try_from(end).ok())
            .and_then(|(start, end)| bytes.get(start..end))
            .ok_or_else(|| truncated(8 + u64::from(chunk_length)))?;
        match (&kind.to_le_bytes(), json.is_some()) {
            (b"JSON", false) => json = Some(data),
            (_, false) => {
                return Err(ParseError::at(
                    Location::Byte(offset + 4),
                    Problem::BadHeader {
                        reason: "the first chunk is not JSON".into(),
                    },
                ))
            }
            (b"BIN\0", true) if bin.is_none() => {
                bin = Some(Bin {
                    data,
                    offset: offset + 8,
                })
            }
            // Later BIN chunks and unknown chunk types are ignored, as "Chunks" asks.
            _ => {}
        }
        offset = end;
    }
    let json = json.ok_or_else(|| {
        ParseError::at(
            Location::Byte(12),
            Problem::Truncated {
                needed: 8,
                available: 0,
            },
        )
    })?;
    Ok(Glb { json, bin })
}

/// Checks that every primitive's POSITION attribute names an existing accessor. gltf-json
/// 1.4's validator indexes the accessor list with it unchecked, and so panics otherwise.
fn check_position_indices(root: &gltf::json::Root) -> Result<(), ParseError> {
    let positions = gltf::json::validation::Checked::Valid(Semantic::Positions);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.get(&positions) {
                if index.value() >= root.accessors.len() {
                    return Err(invalid(format!(
                        "meshes[{m}].primitives[{p}].attributes.POSITION: accessor {} does not exist",
                        index.value()
                    )));
                }
            }
        }
    }
    Ok(())
}

/// Words a `gltf` crate error for [`Problem::Gltf`], listing at most five validation errors.
/// Extensions that store the geometry in a form this reader does not decode.
const COMPRESSION_EXTENSIONS: [&str; 3] = [
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
];

/// What a glTF file that failed to parse or validate is, when it is valid but not what this
/// reader takes, rather than malformed: glTF 1.0 (its JSON differs: objects where 2.0 has
/// arrays, and the parser names only the first difference), or geometry compressed with
/// Draco or meshoptimizer (its accessors have no buffer views: "Missing data"). Read from
/// the JSON again, only on failure.
fn unsupported_kind(json: &[u8]) -> Option<Problem> {
    let value: serde_json::Value = serde_json::from_slice(json).ok()?;
    let version = value.pointer("/asset/version").and_then(|v| v.as_str());
    if let Some(version) = version.filter(|v| v.split('.').next() != Some("2")) {
        return Some(Problem::Unsupported {
            what: format!("glTF {version} (this reader takes glTF 2.0)"),
        });
    }
    let required = value.get("extensionsRequired")?.as_array()?;
    let compressed = required
        .iter()
        .filter_map(|e| e.as_str())
        .find(|e| COMPRESSION_EXTENSIONS.contains(e))?;
    Some(Problem::Unsupported {
        what: format!("glTF geometry compressed with {compressed} (decompress it first)"),
    })
}

fn describe_gltf_error(error: gltf::Error) -> Problem {
    let message = match error {
        gltf::Error::Validation(errors) => {
            let mut listed: Vec<String> = errors
                .iter()
                .take(5)
                .map(|(path, e)| format!("{path}: {e}"))
                .collect();
            if errors.len() > 5 {
                listed.push(format!("and {} more", errors.len() - 5));
            }
            listed.join("; ")
        }
        other => other.to_string(),
    };
    Problem::Gltf { message }
}

/// A [`Problem::Gltf`] for the whole file.
fn invalid(message: String) -> ParseError {
    ParseError::whole(Problem::Gltf { message })
}

/// Every mesh the default scene shows, with its node's world transform. Walks the node
/// hierarchy without recursion and refuses a node reached twice (glTF 2.0, "Nodes and
/// Hierarchy": the hierarchy is a set of disjoint trees), which also rules out cycles.
fn find_mesh_instances(document: &Document) -> Result<Vec<(usize, DMat4)>, ParseError> {
    let Some(scene) = document
        .default_scene()
        .or_else(|| document.scenes().next())
    else {
        return Ok(document
            .meshes()
            .map(|mesh| (mesh.index(), DMat4::IDENTITY))
            .collect());
    };
    let mut reached = vec![false; document.nodes().len()];
    let mut instances = Vec::new();
    let mut stack: Vec<(gltf::Node, DMat4)> =
        scene.nodes().map(|node| (node, DMat4::IDENTITY)).collect();
    stack.reverse();
    while let Some((node, parent)) = stack.pop() {
        let seen = reached
            .get_mut(node.index())
            .ok_or_else(|| invalid(format!("node {} does not exist", node.index())))?;
        if std::mem::replace(seen, true) {
            return Err(invalid(format!(
                "node {} is reached twice from scene {}; the node hierarchy must be a set of trees",
                node.index(),
                scene.index()
            )));
        }
        let world = parent * read_node_transform(&node)?;
        if !world.is_finite() {
            return Err(invalid(format!(
                "node {} has a non-finite world transform",
                node.index()
            )));
        }
        if let Some(mesh) = node.mesh() {
            instances.push((mesh.index(), world));
        }
        let first_child = stack.len();
        stack.extend(node.children().map(|child| (child, world)));
        stack[first_child..].reverse();
    }
    Ok(instances)
}

/// A node's transform relative to its parent, in f64: its matrix, or T × R × S.
fn read_node_transform(node: &gltf::Node) -> Result<DMat4, ParseError> {
    let widen = |v: &[f32]| -> Vec<f64> { v.iter().map(|&x| f64::from(x)).collect() };
    match node.transform() {
        gltf::scene::Transform::Matrix { matrix } => {
            let columns = widen(matrix.as_flattened());
            let columns: [f64; 16] = columns
                .try_into()
                .map_err(|_| invalid(format!("node {} has a malformed matrix", node.index())))?;
            Ok(DMat4::from_cols_array(&columns))
        }
        gltf::scene::Transform::Decomposed {
            translation: t,
            rotation: r,
            scale: s,
        } => {
            let [x, y, z, w] = r.map(f64::from);
            let rotation = DQuat::from_xyzw(x, y, z, w);
            let norm = rotation.length();
            if !(norm.is_finite() && norm > 0.0) {
                return Err(invalid(format!(
                    "node {} has a rotation that is not a unit quaternion",
                    node.index()
                )));
            }
            Ok(DMat4::from_scale_rotation_translation(
                DVec3::from(s.map(f64::from)),
                rotation / norm,
                DVec3::from(t.map(f64::from)),
            ))
        }
    }
}

/// Reads primitives into a soup, resolving each buffer once, when first needed.
struct Reader<'a> {
    document: &'a Document,
    bin: Option<Bin<'a>>,
    base: Option<&'a Path>,
    limits: &'a ImportLimits,
    /// Buffer contents by index, trimmed to their declared length.
    buffers: Vec<Option<Cow<'a, [u8]>>>,
    soup: Soup,
    /// Skipped primitives, counted by description.
    skipped: BTreeMap<&'static str, u64>,
}

/// Where an accessor's elements are: `count` elements of `element` bytes, the first at
/// `start` of `data`, each `stride` bytes after the previous one. Checked to lie in `data`.
struct Elements<'d> {
    data: &'d [u8],
    start: usize,
    stride: usize,
    element: usize,
    count: usize,
}

impl<'d> Elements<'d> {
    /// The bytes of element `i`.
    fn get(&self, i: usize) -> Option<&'d [u8]> {
        let start = i.checked_mul(self.stride)?.checked_add(self.start)?;
        self.data.get(start..start.checked_add(self.element)?)
    }
}

impl<'a> Reader<'a> {
    /// Appends one instance of a mesh: every primitive that draws triangles, transformed.
    fn read_instance(&mut self, mesh: usize, transform: DMat4) -> Result<(), ParseError> {
        let document = self.document;
        let Some(mesh) = document.meshes().nth(mesh) else {
            return Err(invalid(format!("mesh {mesh} does not exist")));
        };
        let mirrored = transform.determinant() < 0.0;
        for primitive in mesh.primitives() {
            let mode = primitive.mode();
            let skipped = match mode {
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => None,
                Mode::Points => Some("point primitives"),
                Mode::Lines | Mode::LineLoop | Mode::LineStrip => Some("line primitives"),
            };
            if let Some(what) = skipped {
                *self.skipped.entry(what).or_default() += 1;
                continue;
            }
            let Some(positions) = primitive.get(&Semantic::Positions) else {
                *self
                    .skipped
                    .entry("triangle primitives without positions")
                    .or_default() += 1;
                continue;
            };
            let corners = match primitive.indices() {
                Some(indices) => indices.count(),
                None => positions.count(),
            };
            let triangles = match mode {
                Mode::Triangles if corners % 3 != 0 => {
                    return Err(invalid(format!(
                        "mesh {} primitive {} has {corners} corners, not a multiple of 3",
                        mesh.index(),
                        primitive.index()
                    )))
                }
                Mode::Triangles => corners / 3,
                _ => corners.saturating_sub(2),
            };
            let first_vertex = self.soup.positions.len();
            let vertices = positions.count();
            check_limit(
                "vertices",
                (first_vertex as u64).saturating_add(vertices as u64),
                self.limits.max_vertices.min(u32::MAX.into()),
            )
            .map_err(ParseError::whole)?;
            check_limit(
                "triangles",
                (self.soup.triangles.len() as u64).saturating_add(triangles as u64),
                self.limits.max_faces,
            )
            .map_err(ParseError::whole)?;
            self.read_positions(&positions, transform)?;
            let indices = match primitive.indices() {
                Some(indices) => self.read_indices(&indices, vertices)?,
                None => (0..vertices)
                    .map(|i| u32::try_from(i).map_err(|_| invalid("too many vertices".into())))
                    .collect::<Result<_, _>>()?,
            };
            let base =
                u32::try_from(first_vertex).map_err(|_| invalid("too many vertices".into()))?;
            let at = |i: usize| -> Result<u32, ParseError> {
                indices
                    .get(i)
                    .and_then(|&v| v.checked_add(base))
                    .ok_or_else(|| invalid("an index past the end of its accessor".into()))
            };
            self.soup.triangles.reserve(triangles);
            for t in 0..triangles {
                let [a, b, c] = match mode {
                    Mode::TriangleStrip if t % 2 == 1 => [t, t + 2, t + 1],
                    Mode::TriangleStrip => [t, t + 1, t + 2],
                    Mode::TriangleFan => [0, t + 1, t + 2],
                    _ => [3 * t, 3 * t + 1, 3 * t + 2],
                };
                let (a, b, c) = (at(a)?, at(b)?, at(c)?);
                self.soup
                    .triangles
                    .push(if mirrored { [a, c, b] } else { [a, b, c] });
            }
        }
        Ok(())
    }

    /// Appends a POSITION accessor's points, transformed, to the soup.
    fn read_positions(&mut self, accessor: &Accessor, transform: DMat4) -> Result<(), ParseError> {
        if accessor.dimensions() != Dimensions::Vec3 || accessor.data_type() != DataType::F32 {
            return Err(ParseError::whole(Problem::Unsupported {
                what: format!(
                    "POSITION accessor {} of {:?} {:?} (only float VEC3 is read)",
                    accessor.index(),
                    accessor.data_type(),
                    accessor.dimensions()
                ),
            }));
        }
        let mut points = Vec::new();
        {
            let elements = self.accessor_bytes(accessor, 12)?;
            points.reserve(elements.count);
            for i in 0..elements.count {
                let bytes = elements
                    .get(i)
                    .ok_or_else(|| invalid("an element outside its accessor".into()))?;
                let mut xyz = [0.0f64; 3];
                for (c, word) in xyz.iter_mut().zip(bytes.chunks_exact(4)) {
                    let word: [u8; 4] = word
                        .try_into()
                        .map_err(|_| invalid("a short float".into()))?;
                    *c = f64::from(f32::from_le_bytes(word));
                }
                points.push(transform.transform_point3(DVec3::from(xyz)));
            }
        }
        let first = self.soup.positions.len() as u64;
        if let Some(bad) = points.iter().position(|p| !p.is_finite()) {
            return Err(ParseError::whole(Problem::NonFiniteCoordinate {
                vertex: first + bad as u64,
            }));
        }
        self.soup.positions.extend(points);
        Ok(())
    }

    /// Reads an indices accessor, each index checked against `vertices`.
    fn read_indices(
        &mut self,
        accessor: &Accessor,
        vertices: usize,
    ) -> Result<Vec<u32>, ParseError> {
        let size = match (accessor.dimensions(), accessor.data_type()) {
            (Dimensions::Scalar, DataType::U8) => 1,
            (Dimensions::Scalar, DataType::U16) => 2,
            (Dimensions::Scalar, DataType::U32) => 4,
            (dimensions, data_type) => {
                return Err(invalid(format!(
                    "indices accessor {} holds {data_type:?} {dimensions:?}, not unsigned integer scalars",
                    accessor.index()
                )))
            }
        };
        let elements = self.accessor_bytes(accessor, size)?;
        let mut indices = Vec::with_capacity(elements.count);
        for i in 0..elements.count {
            let bytes = elements
                .get(i)
                .ok_or_else(|| invalid("an element outside its accessor".into()))?;
            let index = match *bytes {
                [a] => u32::from(a),
                [a, b] => u32::from(u16::from_le_bytes([a, b])),
                [a, b, c, d] => u32::from_le_bytes([a, b, c, d]),
                _ => return Err(invalid("an index of unexpected size".into())),
            };
            if usize::try_from(index).map_or(true, |index| index >= vertices) {
                return Err(ParseError::whole(Problem::IndexOutOfRange {
                    index: i64::from(index),
                    vertex_count: vertices as u64,
                }));
            }
            indices.push(index);
        }
        Ok(indices)
    }

    /// Locates an accessor's elements of `element` bytes, after checking that its buffer view
    /// lies in its buffer and that all its elements lie in the view (glTF 2.0, accessors' "Data
    /// Alignment").
    fn accessor_bytes(
        &mut self,
        accessor: &Accessor,
        element: usize,
    ) -> Result<Elements<'_>, ParseError> {
        let index = accessor.index();
        if accessor.sparse().is_some() {
            return Err(ParseError::whole(Problem::Unsupported {
                what: format!("sparse accessor {index}"),
            }));
        }
        let Some(view) = accessor.view() else {
            return Err(ParseError::whole(Problem::Unsupported {
                what: format!("accessor {index} without a buffer view"),
            }));
        };
        let count = accessor.count();
        let view_start = view.offset();
        let view_length = view.length();
        let stride = view.stride().unwrap_or(element);
        let buffer = view.buffer().index();
        let data = self.buffer(buffer)?;
        let view_end = view_start
            .checked_add(view_length)
            .filter(|&end| end <= data.len())
            .ok_or_else(|| {
                invalid(format!(
                    "buffer view {} (bytes {view_start} + {view_length}) lies outside buffer {buffer} ({} bytes)",
                    view.index(),
                    data.len()
                ))
            })?;
        let view_data = data.get(view_start..view_end).unwrap_or_default();
        if count > 0 {
            let needed = (count - 1)
                .checked_mul(stride)
                .and_then(|n| n.checked_add(accessor.offset()))
                .and_then(|n| n.checked_add(element));
            if needed.is_none_or(|needed| needed > view_length) {
                return Err(invalid(format!(
                    "accessor {index} ({count} elements of {element} bytes every {stride}, from byte {}) does not fit buffer view {} ({view_length} bytes)",
                    accessor.offset(),
                    view.index()
                )));
            }
        }
        Ok(Elements {
            data: view_data,
            start: accessor.offset(),
            stride,
            element,
            count,
        })
    }

    /// A buffer's bytes, trimmed to its declared length, resolved on first use.
    fn buffer(&mut self, index: usize) -> Result<&[u8], ParseError> {
        if self.buffers.get(index).is_some_and(Option::is_none) {
            let resolved = self.resolve_buffer(index)?;
            if let Some(slot) = self.buffers.get_mut(index) {
                *slot = Some(resolved);
            }
        }
        match self.buffers.get(index) {
            Some(Some(data)) => Ok(data),
            _ => Err(invalid(format!("buffer {index} does not exist"))),
        }
    }

    /// Finds a buffer's bytes: the GLB `BIN` chunk, a base64 `data:` URI, or a file relative
    /// to the glTF's folder. Checks the declared length against the limits and against the
    /// bytes actually present.
    fn resolve_buffer(&self, index: usize) -> Result<Cow<'a, [u8]>, ParseError> {
        let document: &'a Document = self.document;
        let Some(buffer) = document.buffers().nth(index) else {
            return Err(invalid(format!("buffer {index} does not exist")));
        };
        let declared = buffer.length();
        check_limit(
            "buffer length in bytes",
            declared as u64,
            self.limits.max_file_bytes,
        )
        .map_err(ParseError::whole)?;
        let truncated = |available: usize, at: Option<Location>| ParseError {
            at,
            problem: Problem::Truncated {
                needed: declared as u64,
                available: available as u64,
            },
        };
        let data: Cow<'a, [u8]> = match buffer.source() {
            Source::Bin => match self.bin {
                Some(bin) if index == 0 => {
                    let data = bin
                        .data
                        .get(..declared)
                        .ok_or_else(|| truncated(bin.data.len(), Some(Location::Byte(bin.offset))))?;
                    Cow::Borrowed(data)
                }
                _ => {
                    return Err(invalid(format!(
                        "buffer {index} has no uri and is not the first buffer of a GLB with a BIN chunk"
                    )))
                }
            },
            Source::Uri(uri) => {
                let mut data = if let Some(rest) = uri.strip_prefix("data:") {
                    decode_data_uri(rest)?
                } else {
                    self.read_buffer_file(uri, declared)?
                };
                if data.len() < declared {
                    return Err(truncated(data.len(), None));
                }
                data.truncate(declared);
                Cow::Owned(data)
            }
        };
        Ok(data)
    }

    /// Reads the first `declared` bytes of a buffer file named by a relative URI.
    fn read_buffer_file(&self, uri: &str, declared: usize) -> Result<Vec<u8>, ParseError> {
        let unsupported = |what: String| ParseError::whole(Problem::Unsupported { what });
        if has_scheme(uri) {
            return Err(unsupported(format!(
                "buffer URI {uri:?}: only relative file names and data: URIs are read"
            )));
        }
        let relative = percent_decode(uri).ok_or_else(|| {
            invalid(format!(
                "buffer URI {uri:?} is not valid percent-encoded UTF-8"
            ))
        })?;
        let relative = Path::new(&relative);
        if !relative
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
        {
            return Err(unsupported(format!(
                "buffer URI {uri:?}: only files in or below the glTF's folder are read"
            )));
        }
        let Some(base) = self.base else {
            return Err(unsupported(format!(
                "buffer URI {uri:?} without a folder to resolve it in"
            )));
        };
        let path = base.join(relative);
        let cannot =
            |e: std::io::Error| invalid(format!("cannot read buffer file {}: {e}", path.display()));
        let file = std::fs::File::open(&path).map_err(cannot)?;
        let metadata = file.metadata().map_err(cannot)?;
        if !metadata.is_file() {
            return Err(invalid(format!(
                "buffer file {} is not a regular file",
                path.display()
            )));
        }
        check_limit(
            "buffer file size in bytes",
            metadata.len(),
            self.limits.max_file_bytes,
        )
        .map_err(ParseError::whole)?;
        if metadata.len() < declared as u64 {
            return Err(ParseError::whole(Problem::Truncated {
                needed: declared as u64,
                available: metadata.len(),
            }));
        }
        let mut data = Vec::with_capacity(declared);
        file.take(declared as u64)
            .read_to_end(&mut data)
            .map_err(cannot)?;
        Ok(data)
    }
}

/// Decodes the part of a `data:` URI after `data:`, if it holds base64 buffer bytes.
fn decode_data_uri(rest: &str) -> Result<Vec<u8>, ParseError> {
    let (media, payload) = rest.split_once(',').unwrap_or((rest, ""));
    match media {
        "application/octet-stream;base64" | "application/gltf-buffer;base64" => {}
        _ => {
            return Err(ParseError::whole(Problem::Unsupported {
                what: format!(
                    "buffer data: URI of type {:?}",
                    super::excerpt(media.as_bytes())
                ),
            }))
        }
    }
    let engine = GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
    );
    engine
        .decode(payload.trim_end())
        .map_err(|e| invalid(format!("buffer data: URI is not valid base64: {e}")))
}

/// Whether a URI starts with a scheme (`http:`, `file:`, `C:` ...), RFC 3986 §3.1.
fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            let mut chars = scheme.chars();
            chars.next().is_some_and(|c| c.is_ascii_alphabetic())
                && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
        }
        None => false,
    }
}

/// Decodes `%XX` escapes; `None` if one is malformed or the result is not UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        if b == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// glTF 1.0 and compressed geometry are named as what they are (valid files this
    /// reader does not take), not as the first place the 2.0 parser stumbles; a malformed
    /// 2.0 file is still malformed.
    #[test]
    fn names_gltf_1_and_compressed_geometry_as_unsupported() {
        let read = |json: &str| parse(json.as_bytes(), None, &ImportLimits::default());
        let unsupported = |json: &str| match read(json) {
            Err(ParseError {
                problem: Problem::Unsupported { what },
                ..
            }) => what,
            other => panic!("{other:?}"),
        };
        let v1 = r#"{"asset": {"version": "1.0"}, "meshes": {"box": {"primitives": []}}}"#;
        assert_eq!(unsupported(v1), "glTF 1.0 (this reader takes glTF 2.0)");
        let draco = r#"{"asset": {"version": "2.0"},
            "extensionsUsed": ["KHR_draco_mesh_compression"],
            "extensionsRequired": ["KHR_draco_mesh_compression"],
            "accessors": [{"componentType": 5126, "count": 3, "type": "VEC3"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "extensions":
                {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}}]}],
            "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0}"#;
        assert_eq!(
            unsupported(draco),
            "glTF geometry compressed with KHR_draco_mesh_compression (decompress it first)"
        );
        let malformed = r#"{"asset": {"version": "2.0"}, "meshes": {"box": {}}}"#;
        assert!(
            matches!(
                read(malformed),
                Err(ParseError {
                    problem: Problem::Gltf { .. },
                    ..
                })
            ),
            "{:?}",
            read(malformed)
        );
    }

    /// A GLB from raw chunks `(type, data)`, with a correct total length.
    fn container(chunks: &[(&[u8; 4], &[u8])]) -> Vec<u8> {
        let mut body = Vec::new();
        for (kind, data) in chunks {
            body.extend_from_slice(&(data.len() as u32).to_le_bytes());
            body.extend_from_slice(*kind);
            body.extend_from_slice(data);
        }
        let mut out = b"glTF".to_vec();
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(12 + body.len() as u32).to_le_bytes());
        out.extend(body);
        out
    }

    #[test]
    fn splits_chunks_ignoring_unknown_and_later_bin_chunks() {
        let bytes = container(&[
            (b"JSON", b"{}  "),
            (b"XTRA", b"zzzz"),
            (b"BIN\0", b"abcd"),
            (b"BIN\0", b"efgh"),
        ]);
        let glb = split_glb(&bytes).unwrap();
        assert_eq!(glb.json, b"{}  ");
        let bin = glb.bin.unwrap();
        assert_eq!(bin.data, b"abcd");
        assert_eq!(bin.offset, 12 + 12 + 12 + 8);
    }

    #[test]
    fn locates_chunk_problems() {
        let mut bytes = container(&[(b"JSON", b"{}  "), (b"BIN\0", b"abcd")]);
        // The BIN chunk claims 100 bytes.
        bytes[24..28].copy_from_slice(&100u32.to_le_bytes());
        let e = split_glb(&bytes).err().unwrap();
        assert_eq!(e.at, Some(Location::Byte(24)));
        assert_eq!(
            e.problem,
            Problem::Truncated {
                needed: 108,
                available: 12
            }
        );
        // Four stray bytes after the last chunk: too few for a chunk header.
        let mut bytes = container(&[(b"JSON", b"{}  ")]);
        bytes.extend_from_slice(b"\0\0\0\0");
        bytes[8..12].copy_from_slice(&28u32.to_le_bytes());
        let e = split_glb(&bytes).err().unwrap();
        assert_eq!(e.at, Some(Location::Byte(24)));
        assert!(matches!(
            e.problem,
            Problem::Truncated {
                needed: 8,
                available: 4
            }
        ));
        // A header and nothing else.
        let bytes = container(&[]);
        let e = split_glb(&bytes).err().unwrap();
        assert_eq!(e.at, Some(Location::Byte(12)));
        // A chunk length near u32::MAX does not overflow anything.
        let mut bytes = container(&[(b"JSON", b"{}  ")]);
        bytes[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(split_glb(&bytes).is_err());
    }

    #[test]
    fn recognises_schemes() {
        for uri in [
            "http://x/a.bin",
            "https://x",
            "file:///a",
            "C:/a.bin",
            "data:x",
            "a+b.c-d:x",
        ] {
            assert!(has_scheme(uri), "{uri}");
        }
        for uri in ["a.bin", "dir/a.bin", "a%3Ab.bin", "./a:b.bin", "1a:b", ":a"] {
            assert!(!has_scheme(uri), "{uri}");
        }
    }

    #[test]
    fn percent_decodes_strictly() {
        assert_eq!(percent_decode("a%20b%2Fc").as_deref(), Some("a b/c"));
        assert_eq!(percent_decode("caf%C3%A9").as_deref(), Some("café"));
        for bad in ["a%2", "a%zz", "%", "%FF", "a%C3"] {
            assert_eq!(percent_decode(bad), None, "{bad}");
        }
    }

    #[test]
    fn decodes_data_uris_with_or_without_padding() {
        assert_eq!(
            decode_data_uri("application/octet-stream;base64,AAEC").unwrap(),
            [0, 1, 2]
        );
        assert_eq!(
            decode_data_uri("application/gltf-buffer;base64,AAE=").unwrap(),
            [0, 1]
        );
        assert_eq!(
            decode_data_uri("application/gltf-buffer;base64,AAE").unwrap(),
            [0, 1]
        );
        assert!(matches!(
            decode_data_uri("image/png;base64,AAEC")
                .unwrap_err()
                .problem,
            Problem::Unsupported { .. }
        ));
    }
}
