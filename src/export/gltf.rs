//! glTF 2.0 writer: GLB, `.gltf` with an external `.bin`, and `.gltf` with an embedded
//! buffer. Follows the glTF 2.0 specification (Khronos, 2021): one buffer, one bufferView per
//! attribute, 4-byte aligned; `POSITION` with its required `min`/`max` (§3.7.2.1, §5.1.1);
//! unit `NORMAL`s (§3.7.2.1); optional normalised `UNSIGNED_BYTE` `COLOR_0`; `UNSIGNED_SHORT`
//! indices when every index fits, else `UNSIGNED_INT` (§3.7.2.2: the all-ones value is
//! reserved); GLB chunks padded to 4 bytes, JSON with spaces and BIN with zeros (§4.4.3).

use super::{invalid, Checked, ExportError};
use crate::mesh::angle_weighted_normals;
use base64::Engine;
use glam::{DVec3, Vec3};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// `ARRAY_BUFFER`, the bufferView target for vertex attributes.
const ARRAY_BUFFER: u32 = 34962;
/// `ELEMENT_ARRAY_BUFFER`, the bufferView target for indices.
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
/// Accessor component types.
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const FLOAT: u32 = 5126;
/// GLB magic `glTF`, container version, and chunk types `JSON` and `BIN\0`.
const GLB_MAGIC: u32 = 0x4654_6C67;
const GLB_VERSION: u32 = 2;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// The buffer file that goes with a `.gltf`: `<stem>.bin` in the same folder.
pub(super) fn buffer_path(gltf: &Path) -> Option<PathBuf> {
    gltf.file_stem()?;
    Some(gltf.with_extension("bin"))
}

/// Percent-encodes a file name for a relative URI (RFC 3986): unreserved characters stay,
/// every other byte becomes `%XX`.
pub(super) fn encode_uri(name: &[u8]) -> String {
    let mut uri = String::with_capacity(name.len());
    for &b in name {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~') {
            uri.push(char::from(b));
        } else {
            uri.push_str(&format!("%{b:02X}"));
        }
    }
    uri
}

/// A GLB file: header, JSON chunk, BIN chunk.
pub(super) fn encode_glb(data: &Checked<'_>) -> Result<Vec<u8>, ExportError> {
    let (document, bin) = build(data, None)?;
    let mut json = serde_json::to_vec(&document).map_err(json_error)?;
    pad(&mut json, b' ');
    let too_large = || {
        invalid(
            "size",
            format!(
                "the GLB would exceed the {} bytes its 32-bit length field allows",
                u32::MAX
            ),
        )
    };
    let total = 12 + 8 + json.len() as u64 + 8 + bin.len() as u64;
    let total = u32::try_from(total).map_err(|_| too_large())?;
    let json_len = u32::try_from(json.len()).map_err(|_| too_large())?;
    let bin_len = u32::try_from(bin.len()).map_err(|_| too_large())?;
    let mut out = Vec::with_capacity(total as usize);
    for word in [GLB_MAGIC, GLB_VERSION, total, json_len, CHUNK_JSON] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&json);
    out.extend_from_slice(&bin_len.to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}

/// A `.gltf` document referring to its buffer by `uri`, and the buffer's bytes.
pub(super) fn encode_separate(
    data: &Checked<'_>,
    uri: &str,
) -> Result<(Vec<u8>, Vec<u8>), ExportError> {
    let (document, bin) = build(data, Some(uri.to_owned()))?;
    let mut json = serde_json::to_vec(&document).map_err(json_error)?;
    json.push(b'\n');
    Ok((json, bin))
}

/// A `.gltf` document with its buffer embedded as a base64 `data:` URI.
pub(super) fn encode_embedded(data: &Checked<'_>) -> Result<Vec<u8>, ExportError> {
    let (mut document, bin) = build(data, None)?;
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    document["buffers"][0]["uri"] = Value::String(uri);
    let mut json = serde_json::to_vec(&document).map_err(json_error)?;
    json.push(b'\n');
    Ok(json)
}

/// Serialising a `serde_json::Value` to memory cannot fail; reported as data error if it does.
fn json_error(e: serde_json::Error) -> ExportError {
    invalid("glTF JSON", e.to_string())
}

/// Pads `bytes` with `fill` to a multiple of 4.
fn pad(bytes: &mut Vec<u8>, fill: u8) {
    while bytes.len() % 4 != 0 {
        bytes.push(fill);
    }
}

/// Unit `f32` normals: those given, or the angle-weighted ones, renormalised in `f32` so
/// that they are unit length to `f32` precision as the specification requires.
fn unit_normals(data: &Checked<'_>) -> Vec<Vec3> {
    let computed;
    let normals = match data.normals {
        Some(given) => given,
        None => {
            computed = angle_weighted_normals(data.positions, data.triangles);
            &computed
        }
    };
    normals.iter().map(|&n| to_unit_f32(n)).collect()
}

/// `n` as a unit `f32` vector; `check` guarantees that `n` is finite and non-zero.
fn to_unit_f32(n: DVec3) -> Vec3 {
    let unit = n.try_normalize().unwrap_or(DVec3::Z).as_vec3();
    unit.try_normalize().unwrap_or(Vec3::Z)
}

/// The glTF document (without a buffer URI unless given) and its binary buffer.
fn build(data: &Checked<'_>, uri: Option<String>) -> Result<(Value, Vec<u8>), ExportError> {
    let n = data.positions.len();
    let index_count = data.triangles.len() * 3;
    // u16 indices when the largest index (n − 1) is below the reserved 0xFFFF.
    let short_indices = n <= usize::from(u16::MAX);
    let index_size = if short_indices { 2 } else { 4 };
    let color_bytes = if data.colors.is_some() { 4 } else { 0 };
    let size = (n as u64) * (12 + 12 + color_bytes) + (index_count as u64) * index_size + 3;
    let size = usize::try_from(size).map_err(|_| {
        invalid(
            "size",
            format!("a {size}-byte buffer does not fit in memory"),
        )
    })?;
    let mut bin: Vec<u8> = Vec::with_capacity(size);
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = serde_json::Map::new();

    // POSITION with exact f32 bounds.
    let positions: Vec<Vec3> = data.positions.iter().map(|p| p.as_vec3()).collect();
    let (min, max) = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let start = bin.len();
    for p in &positions {
        extend_vec3(&mut bin, *p);
    }
    attributes.insert("POSITION".into(), json!(accessors.len()));
    accessors.push(json!({
        "bufferView": views.len(),
        "componentType": FLOAT,
        "count": n,
        "type": "VEC3",
        "min": [min.x, min.y, min.z],
        "max": [max.x, max.y, max.z],
    }));
    views.push(view(start, bin.len(), ARRAY_BUFFER));

    // NORMAL, always present and unit length.
    let start = bin.len();
    for normal in unit_normals(data) {
        extend_vec3(&mut bin, normal);
    }
    attributes.insert("NORMAL".into(), json!(accessors.len()));
    accessors.push(json!({
        "bufferView": views.len(),
        "componentType": FLOAT,
        "count": n,
        "type": "VEC3",
    }));
    views.push(view(start, bin.len(), ARRAY_BUFFER));

    // COLOR_0, normalised RGBA bytes.
    if let Some(colors) = data.colors {
        let start = bin.len();
        for c in colors {
            bin.extend_from_slice(c);
        }
        attributes.insert("COLOR_0".into(), json!(accessors.len()));
        accessors.push(json!({
            "bufferView": views.len(),
            "componentType": UNSIGNED_BYTE,
            "normalized": true,
            "count": n,
            "type": "VEC4",
        }));
        views.push(view(start, bin.len(), ARRAY_BUFFER));
    }

    // Indices last: 2-byte indices may leave the buffer 2 bytes short of alignment.
    let start = bin.len();
    for &index in data.triangles.iter().flatten() {
        if short_indices {
            // `check` bounded every index by n ≤ u16::MAX.
            let index = u16::try_from(index)
                .map_err(|_| invalid("triangle index", format!("{index} does not fit 16 bits")))?;
            bin.extend_from_slice(&index.to_le_bytes());
        } else {
            bin.extend_from_slice(&index.to_le_bytes());
        }
    }
    let indices = accessors.len();
    accessors.push(json!({
        "bufferView": views.len(),
        "componentType": if short_indices { UNSIGNED_SHORT } else { UNSIGNED_INT },
        "count": index_count,
        "type": "SCALAR",
    }));
    views.push(view(start, bin.len(), ELEMENT_ARRAY_BUFFER));
    pad(&mut bin, 0);

    let mut buffer = json!({ "byteLength": bin.len() });
    if let Some(uri) = uri {
        buffer["uri"] = Value::String(uri);
    }
    let document = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("ellip ", env!("CARGO_PKG_VERSION")),
        },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{
            "primitives": [{
                "attributes": attributes,
                "indices": indices,
                "material": 0,
            }],
        }],
        "materials": [{
            "name": "ellip default",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.8, 0.8, 0.8, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.6,
            },
        }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [buffer],
    });
    Ok((document, bin))
}

/// Appends a vector's three little-endian `f32`s.
fn extend_vec3(bin: &mut Vec<u8>, v: Vec3) {
    for x in v.to_array() {
        bin.extend_from_slice(&x.to_le_bytes());
    }
}

/// A bufferView over `start..end` of buffer 0.
fn view(start: usize, end: usize, target: u32) -> Value {
    json!({
        "buffer": 0,
        "byteOffset": start,
        "byteLength": end - start,
        "target": target,
    })
}
