//! PLY reader (the Stanford polygon format), ASCII and binary of either byte order.
//!
//! A PLY file is a text header, then each declared element's records in header order:
//!
//! ```text
//! ply
//! format ascii 1.0                      (or binary_little_endian / binary_big_endian)
//! comment …                             (and obj_info …, anywhere in the header)
//! element vertex 8
//! property float x                      (y, z; any scalar type; other properties skipped)
//! element face 6
//! property list uchar int vertex_indices   (or vertex_index; any integer types)
//! end_header
//! ```
//!
//! Only the `vertex` element's `x`, `y`, `z` and the `face` element's index list are read;
//! every other element and property is skipped, lists included, in either encoding. Faces
//! of more than three vertices are fanned into triangles.
//!
//! Header problems are located by line (the header is text, even in binary files); problems
//! in the data by line for ASCII and by byte offset for binary. Before anything is allocated,
//! the declared counts are checked against [`ImportLimits`] and against the bytes present:
//! every record takes at least its fixed-size properties and list lengths (binary) or two
//! bytes per property (ASCII: a value and a separator).

use super::{check_limit, excerpt, parse_word, ImportLimits, Location, ParseError, Problem, Soup};
use glam::DVec3;

/// Parses a PLY file.
pub(crate) fn parse(bytes: &[u8], limits: &ImportLimits) -> Result<Soup, ParseError> {
    let header = read_header(bytes)?;
    let plan = plan_reading(&header)?;
    check_counts(&header, &plan, bytes, limits)?;
    let body = bytes.get(header.body_start..).unwrap_or_default();
    match header.encoding {
        Encoding::Ascii => {
            let mut reader = AsciiBody::new(body, header.lines + 1);
            read_body(&mut reader, &header, &plan, limits)
        }
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
            let mut reader = BinaryBody {
                bytes,
                pos: header.body_start,
                last: header.body_start,
                big_endian: header.encoding == Encoding::BinaryBigEndian,
            };
            read_body(&mut reader, &header, &plan, limits)
        }
    }
}

/// How the data after the header is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// The type a header names, by its classic name or its sized alias.
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Bytes in binary encodings.
    fn size(self) -> u64 {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

/// A property's type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Scalar(Scalar),
    List { length: Scalar, item: Scalar },
}

/// A declared property.
#[derive(Debug)]
struct Property<'a> {
    name: &'a [u8],
    kind: Kind,
}

/// A declared element.
#[derive(Debug)]
struct Element<'a> {
    name: &'a [u8],
    count: u64,
    properties: Vec<Property<'a>>,
    /// Header line that declares it.
    line: u64,
}

impl Element<'_> {
    /// Fewest bytes a record can take: fixed-size values and list lengths (binary), or a
    /// value and a separator per property (ASCII).
    fn min_record_bytes(&self, encoding: Encoding) -> u64 {
        match encoding {
            Encoding::Ascii => 2 * self.properties.len() as u64,
            _ => self
                .properties
                .iter()
                .map(|p| match p.kind {
                    Kind::Scalar(s) | Kind::List { length: s, .. } => s.size(),
                })
                .sum(),
        }
    }

    /// Whether every record has the same size.
    fn is_fixed_size(&self) -> bool {
        self.properties
            .iter()
            .all(|p| matches!(p.kind, Kind::Scalar(_)))
    }
}

/// The parsed header.
#[derive(Debug)]
struct Header<'a> {
    encoding: Encoding,
    elements: Vec<Element<'a>>,
    /// Byte offset of the first byte after `end_header`'s line.
    body_start: usize,
    /// Number of header lines.
    lines: u64,
    /// How many header lines had a keyword the format does not have (skipped). Blender
    /// 2.4x wrote its "Created by Blender3D …" banner without `comment`.
    skipped: u64,
    /// The first of them: (line, keyword).
    first_skipped: Option<(u64, String)>,
}

/// Reads the header, up to and including the `end_header` line.
fn read_header(bytes: &[u8]) -> Result<Header<'_>, ParseError> {
    if bytes.is_empty() {
        return Err(ParseError::whole(Problem::Empty));
    }
    let mut lines = HeaderLines {
        bytes,
        pos: 0,
        line: 0,
    };
    if lines.next().map(trim_end) != Some(&b"ply"[..]) {
        return Err(ParseError::whole(Problem::NotThisFormat {
            expected: "PLY",
        }));
    }
    let mut encoding = None;
    let mut elements: Vec<Element<'_>> = Vec::new();
    let (mut skipped, mut first_skipped) = (0, None);
    // The first unknown line since the last element line.
    let mut since_element: Option<(u64, String)> = None;
    loop {
        let Some(text) = lines.next() else {
            return Err(bad_header(lines.line, "no end_header line".into()));
        };
        let at = lines.line;
        let mut words = text
            .split(u8::is_ascii_whitespace)
            .filter(|w| !w.is_empty());
        let Some(keyword) = words.next() else {
            continue; // a blank line
        };
        match keyword {
            b"comment" | b"obj_info" => {}
            b"format" => {
                if encoding.is_some() {
                    return Err(bad_header(at, "a second format line".into()));
                }
                encoding = Some(read_format(words.next(), words.next(), at)?);
            }
            b"element" => {
                since_element = None;
                let (Some(name), Some(count)) = (words.next(), words.next()) else {
                    return Err(bad_header(at, "an element needs a name and a count".into()));
                };
                let count = parse_word::<u64>(count)
                    .ok_or_else(|| bad_header(at, format!("element count {:?}", excerpt(count))))?;
                elements.push(Element {
                    name,
                    count,
                    properties: Vec::new(),
                    line: at,
                });
            }
            b"property" => {
                // Properties after an unknown line belong to what it declared: it was no
                // comment (a misspelt `element`), and the body cannot be read without it.
                if let Some((line, keyword)) = since_element.take() {
                    return Err(bad_header(line, format!("unknown keyword {keyword:?}")));
                }
                let Some(element) = elements.last_mut() else {
                    return Err(bad_header(at, "a property before any element".into()));
                };
                element.properties.push(read_property(words, at)?);
            }
            b"end_header" => break,
            // A line the format does not define, with no property after it, declares
            // nothing the body depends on: skipped, and reported (read as the comment its
            // writer meant).
            other => {
                skipped += 1;
                first_skipped.get_or_insert_with(|| (at, excerpt(other)));
                since_element.get_or_insert_with(|| (at, excerpt(other)));
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(bad_header(lines.line, "no format line".into()));
    };
    Ok(Header {
        encoding,
        elements,
        body_start: lines.pos,
        lines: lines.line,
        skipped,
        first_skipped,
    })
}

/// Reads `format <encoding> <version>`.
fn read_format(
    encoding: Option<&[u8]>,
    version: Option<&[u8]>,
    at: u64,
) -> Result<Encoding, ParseError> {
    let encoding = match encoding.unwrap_or_default() {
        b"ascii" => Encoding::Ascii,
        b"binary_little_endian" => Encoding::BinaryLittleEndian,
        b"binary_big_endian" => Encoding::BinaryBigEndian,
        other => {
            return Err(bad_header(
                at,
                format!("unknown format {:?}", excerpt(other)),
            ))
        }
    };
    match version {
        Some(b"1.0" | b"1") => Ok(encoding),
        Some(other) => Err(ParseError::at(
            Location::Line(at),
            Problem::Unsupported {
                what: format!("PLY version {}", excerpt(other)),
            },
        )),
        None => Err(bad_header(at, "the format line has no version".into())),
    }
}

/// Reads the rest of a `property` line.
fn read_property<'a>(
    mut words: impl Iterator<Item = &'a [u8]>,
    at: u64,
) -> Result<Property<'a>, ParseError> {
    let scalar = |word: Option<&[u8]>| {
        let word = word.unwrap_or_default();
        Scalar::from_name(word)
            .ok_or_else(|| bad_header(at, format!("unknown property type {:?}", excerpt(word))))
    };
    let first = words.next();
    let kind = if first == Some(b"list") {
        Kind::List {
            length: scalar(words.next())?,
            item: scalar(words.next())?,
        }
    } else {
        Kind::Scalar(scalar(first)?)
    };
    let name = words
        .next()
        .ok_or_else(|| bad_header(at, "a property without a name".into()))?;
    Ok(Property { name, kind })
}

/// Which elements and properties hold the mesh.
#[derive(Debug)]
struct Plan {
    /// Index of the `vertex` element.
    vertex: usize,
    /// For each vertex property, the axis it gives (0, 1, 2 for x, y, z), if any.
    axes: Vec<Option<usize>>,
    /// Index of the `face` element and of its index list property, if there are faces.
    face: Option<(usize, usize)>,
}

/// Finds the vertex coordinates and face index lists in the header.
fn plan_reading(header: &Header<'_>) -> Result<Plan, ParseError> {
    let find_unique = |name: &[u8]| -> Result<Option<usize>, ParseError> {
        let mut found = header
            .elements
            .iter()
            .enumerate()
            .filter(|(_, e)| e.name == name);
        let first = found.next().map(|(i, _)| i);
        match found.next() {
            Some((_, second)) => Err(bad_header(
                second.line,
                format!("a second {} element", excerpt(name)),
            )),
            None => Ok(first),
        }
    };
    let last_line = header.lines;
    let vertex =
        find_unique(b"vertex")?.ok_or_else(|| bad_header(last_line, "no vertex element".into()))?;
    let element = header
        .elements
        .get(vertex)
        .map_or(&[][..], |e| &e.properties);
    let element_line = header.elements.get(vertex).map_or(last_line, |e| e.line);
    let mut axes = vec![None; element.len()];
    for (axis, name) in [b"x", b"y", b"z"].into_iter().enumerate() {
        let Some(i) = element.iter().position(|p| p.name == name) else {
            return Err(bad_header(
                element_line,
                format!("the vertex element has no {} property", excerpt(name)),
            ));
        };
        if matches!(element.get(i).map(|p| p.kind), Some(Kind::List { .. })) {
            return Err(bad_header(
                element_line,
                format!("vertex property {} is a list", excerpt(name)),
            ));
        }
        if let Some(slot) = axes.get_mut(i) {
            *slot = Some(axis);
        }
    }

    let face = match find_unique(b"face")? {
        None => None,
        Some(f) => {
            let element = header.elements.get(f);
            let properties = element.map_or(&[][..], |e| &e.properties);
            let line = element.map_or(last_line, |e| e.line);
            let list = properties
                .iter()
                .position(|p| p.name == b"vertex_indices" || p.name == b"vertex_index")
                .ok_or_else(|| {
                    bad_header(line, "the face element has no vertex_indices list".into())
                })?;
            if !matches!(
                properties.get(list).map(|p| p.kind),
                Some(Kind::List { .. })
            ) {
                return Err(bad_header(
                    line,
                    "the face vertex indices are not a list".into(),
                ));
            }
            Some((f, list))
        }
    };
    Ok(Plan { vertex, axes, face })
}

/// Checks the declared counts against the limits and the bytes present, so that what is
/// allocated afterwards is bounded by both.
fn check_counts(
    header: &Header<'_>,
    plan: &Plan,
    bytes: &[u8],
    limits: &ImportLimits,
) -> Result<(), ParseError> {
    let count_of = |i: usize| header.elements.get(i).map_or(0, |e| e.count);
    let line_of = |i: usize| Location::Line(header.elements.get(i).map_or(0, |e| e.line));
    let vertex_limit = limits.max_vertices.min(u64::from(u32::MAX));
    check_limit("vertices", count_of(plan.vertex), vertex_limit)
        .map_err(|p| ParseError::at(line_of(plan.vertex), p))?;
    if let Some((f, _)) = plan.face {
        check_limit("faces", count_of(f), limits.max_faces)
            .map_err(|p| ParseError::at(line_of(f), p))?;
    }

    let body_len = bytes.len().saturating_sub(header.body_start) as u64;
    // In ASCII the last value needs no separator after it.
    let slack = u64::from(header.encoding == Encoding::Ascii);
    let mut used: u64 = 0;
    for element in &header.elements {
        let needed = element
            .count
            .saturating_mul(element.min_record_bytes(header.encoding));
        let available = (body_len + slack).saturating_sub(used);
        if needed > available {
            let at = match header.encoding {
                Encoding::Ascii => Location::Line(element.line),
                _ => Location::Byte(header.body_start as u64 + used),
            };
            return Err(ParseError::at(at, Problem::Truncated { needed, available }));
        }
        used += needed;
    }
    Ok(())
}

/// Reads every element in header order, keeping vertices and faces.
fn read_body<B: Body>(
    body: &mut B,
    header: &Header<'_>,
    plan: &Plan,
    limits: &ImportLimits,
) -> Result<Soup, ParseError> {
    let count_of = |i: usize| header.elements.get(i).map_or(0, |e| e.count);
    // Both counts were checked against the bytes present.
    let to_usize = |n: u64| usize::try_from(n).unwrap_or(usize::MAX);
    let mut soup = Soup {
        positions: Vec::with_capacity(to_usize(count_of(plan.vertex))),
        triangles: Vec::with_capacity(plan.face.map_or(0, |(f, _)| to_usize(count_of(f)))),
        ..Soup::default()
    };
    if let Some((line, keyword)) = &header.first_skipped {
        let count = header.skipped;
        soup.warnings.push(format!(
            "skipped {count} PLY header line(s) with an unknown keyword (the first: line \
             {line}, {keyword:?})"
        ));
    }
    let vertex_count = count_of(plan.vertex);
    for (e, element) in header.elements.iter().enumerate() {
        let what = if e == plan.vertex {
            "vertices"
        } else if plan.face.is_some_and(|(f, _)| f == e) {
            "faces"
        } else {
            "element records"
        };
        let result = if e == plan.vertex {
            read_vertices(body, element, &plan.axes, &mut soup)
        } else if let Some((_, list)) = plan.face.filter(|&(f, _)| f == e) {
            let faces = FaceReading {
                list,
                vertex_count,
                max_triangles: limits.max_faces,
            };
            read_faces(body, element, &faces, &mut soup)
        } else {
            if element.count > 0 {
                soup.warnings.push(format!(
                    "skipped the {} PLY {:?} records",
                    element.count,
                    excerpt(element.name)
                ));
            }
            skip_element(body, element)
        };
        // Running out of ASCII values is a short count, not a syntax error.
        result.map_err(|e| match body.ended() {
            Some(found) => ParseError {
                at: e.at,
                problem: Problem::CountMismatch {
                    what,
                    declared: element.count,
                    found,
                },
            },
            None => e,
        })?;
    }
    Ok(soup)
}

/// Reads the vertex element's records.
fn read_vertices<B: Body>(
    body: &mut B,
    element: &Element<'_>,
    axes: &[Option<usize>],
    soup: &mut Soup,
) -> Result<(), ParseError> {
    for vertex in 0..element.count {
        body.start_record(vertex);
        let mut p = [0.0; 3];
        for (property, axis) in element.properties.iter().zip(axes) {
            match (property.kind, axis.and_then(|a| p.get_mut(a))) {
                (Kind::Scalar(ty), Some(c)) => {
                    *c = body.read_f64(ty)?;
                    if !c.is_finite() {
                        return Err(ParseError::at(
                            body.at(),
                            Problem::NonFiniteCoordinate { vertex },
                        ));
                    }
                }
                _ => skip_property(body, property.kind)?,
            }
        }
        soup.positions.push(DVec3::from_array(p));
    }
    Ok(())
}

/// What [`read_faces`] needs to know.
struct FaceReading {
    /// Index of the vertex index list among the face properties.
    list: usize,
    vertex_count: u64,
    max_triangles: u64,
}

/// Reads the face element's records, fanning polygons into triangles.
fn read_faces<B: Body>(
    body: &mut B,
    element: &Element<'_>,
    faces: &FaceReading,
    soup: &mut Soup,
) -> Result<(), ParseError> {
    for face in 0..element.count {
        body.start_record(face);
        for (i, property) in element.properties.iter().enumerate() {
            match property.kind {
                Kind::List { length, item } if i == faces.list => {
                    read_face(body, length, item, faces, soup)?;
                }
                kind => skip_property(body, kind)?,
            }
        }
    }
    Ok(())
}

/// Reads one face's index list.
fn read_face<B: Body>(
    body: &mut B,
    length: Scalar,
    item: Scalar,
    faces: &FaceReading,
    soup: &mut Soup,
) -> Result<(), ParseError> {
    let n = read_list_length(body, length)?;
    if n < 3 {
        return Err(ParseError::at(
            body.at(),
            Problem::FaceTooSmall { vertices: n },
        ));
    }
    let mut read_index = || -> Result<u32, ParseError> {
        let index = body.read_int(item, "a vertex index")?;
        u32::try_from(index)
            .ok()
            .filter(|&i| u64::from(i) < faces.vertex_count)
            .ok_or_else(|| {
                ParseError::at(
                    body.at(),
                    Problem::IndexOutOfRange {
                        index,
                        vertex_count: faces.vertex_count,
                    },
                )
            })
    };
    let first = read_index()?;
    let mut previous = read_index()?;
    for _ in 2..n {
        let next = read_index()?;
        if soup.triangles.len() as u64 >= faces.max_triangles {
            return Err(ParseError::at(
                body.at(),
                Problem::LimitsExceeded {
                    what: "triangles",
                    requested: soup.triangles.len() as u64 + 1,
                    max: faces.max_triangles,
                },
            ));
        }
        soup.triangles.push([first, previous, next]);
        previous = next;
    }
    if n > 3 {
        soup.triangulated_polygons += 1;
    }
    Ok(())
}

/// Skips every record of an element that is not read.
fn skip_element<B: Body>(body: &mut B, element: &Element<'_>) -> Result<(), ParseError> {
    if element.properties.is_empty() {
        // Records of nothing: however many are declared, there is nothing to read.
        return Ok(());
    }
    if element.is_fixed_size() && !B::IS_TEXT {
        // The same bytes in a different order: a single skip per property.
        for property in &element.properties {
            if let Kind::Scalar(ty) = property.kind {
                body.skip(ty, element.count)?;
            }
        }
        return Ok(());
    }
    for record in 0..element.count {
        body.start_record(record);
        for property in &element.properties {
            skip_property(body, property.kind)?;
        }
    }
    Ok(())
}

/// Skips one property's value or list.
fn skip_property<B: Body>(body: &mut B, kind: Kind) -> Result<(), ParseError> {
    match kind {
        Kind::Scalar(ty) => body.skip(ty, 1),
        Kind::List { length, item } => {
            let n = read_list_length(body, length)?;
            body.skip(item, n)
        }
    }
}

/// Reads a list's length, which must not be negative.
fn read_list_length<B: Body>(body: &mut B, ty: Scalar) -> Result<u64, ParseError> {
    let n = body.read_int(ty, "a list length")?;
    u64::try_from(n).map_err(|_| {
        ParseError::at(
            body.at(),
            Problem::Syntax {
                expected: "a list length",
                found: n.to_string(),
            },
        )
    })
}

/// The data after the header, in either encoding.
trait Body {
    /// Whether values are words of text (so their sizes vary).
    const IS_TEXT: bool;
    /// Reads a value as a double.
    fn read_f64(&mut self, ty: Scalar) -> Result<f64, ParseError>;
    /// Reads a value that must be an integer.
    fn read_int(&mut self, ty: Scalar, expected: &'static str) -> Result<i64, ParseError>;
    /// Skips `n` values.
    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), ParseError>;
    /// Where the value last read starts.
    fn at(&self) -> Location;
    /// Notes that record number `record` of an element begins.
    fn start_record(&mut self, record: u64);
    /// If the data ran out while reading an element, how many of its records were complete.
    fn ended(&self) -> Option<u64>;
}

/// Binary data, either byte order.
struct BinaryBody<'a> {
    /// The whole file, so that offsets are file offsets.
    bytes: &'a [u8],
    pos: usize,
    /// Start of the value last read.
    last: usize,
    big_endian: bool,
}

impl BinaryBody<'_> {
    /// The next `N` bytes.
    fn take<const N: usize>(&mut self) -> Result<[u8; N], ParseError> {
        let value = self
            .pos
            .checked_add(N)
            .and_then(|end| self.bytes.get(self.pos..end))
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or_else(|| self.truncated(N as u64))?;
        self.last = self.pos;
        self.pos += N;
        Ok(value)
    }

    fn truncated(&self, needed: u64) -> ParseError {
        ParseError::at(
            Location::Byte(self.pos as u64),
            Problem::Truncated {
                needed,
                available: self.bytes.len().saturating_sub(self.pos) as u64,
            },
        )
    }
}

/// Decodes a number of type `$t` from the next bytes in the body's byte order.
macro_rules! read_number {
    ($body:expr, $t:ty) => {{
        let b = $body.take::<{ std::mem::size_of::<$t>() }>()?;
        if $body.big_endian {
            <$t>::from_be_bytes(b)
        } else {
            <$t>::from_le_bytes(b)
        }
    }};
}

impl Body for BinaryBody<'_> {
    const IS_TEXT: bool = false;

    fn read_f64(&mut self, ty: Scalar) -> Result<f64, ParseError> {
        Ok(match ty {
            Scalar::I8 => f64::from(read_number!(self, i8)),
            Scalar::U8 => f64::from(read_number!(self, u8)),
            Scalar::I16 => f64::from(read_number!(self, i16)),
            Scalar::U16 => f64::from(read_number!(self, u16)),
            Scalar::I32 => f64::from(read_number!(self, i32)),
            Scalar::U32 => f64::from(read_number!(self, u32)),
            Scalar::F32 => f64::from(read_number!(self, f32)),
            Scalar::F64 => read_number!(self, f64),
        })
    }

    fn read_int(&mut self, ty: Scalar, expected: &'static str) -> Result<i64, ParseError> {
        Ok(match ty {
            Scalar::I8 => i64::from(read_number!(self, i8)),
            Scalar::U8 => i64::from(read_number!(self, u8)),
            Scalar::I16 => i64::from(read_number!(self, i16)),
            Scalar::U16 => i64::from(read_number!(self, u16)),
            Scalar::I32 => i64::from(read_number!(self, i32)),
            Scalar::U32 => i64::from(read_number!(self, u32)),
            Scalar::F32 | Scalar::F64 => {
                let x = self.read_f64(ty)?;
                float_to_int(x).ok_or_else(|| {
                    ParseError::at(
                        self.at(),
                        Problem::Syntax {
                            expected,
                            found: x.to_string(),
                        },
                    )
                })?
            }
        })
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), ParseError> {
        let needed = ty.size().saturating_mul(n);
        let available = self.bytes.len().saturating_sub(self.pos) as u64;
        if needed > available {
            return Err(self.truncated(needed));
        }
        // `needed` is at most the bytes left, so it fits.
        self.last = self.pos;
        self.pos += needed as usize;
        Ok(())
    }

    fn at(&self) -> Location {
        Location::Byte(self.last as u64)
    }

    fn start_record(&mut self, _record: u64) {}

    fn ended(&self) -> Option<u64> {
        None
    }
}

/// An integer-valued float as an integer.
fn float_to_int(x: f64) -> Option<i64> {
    // The range check keeps the cast exact.
    (x.fract() == 0.0 && x.abs() < 9.0e18).then_some(x as i64)
}

/// ASCII data: whitespace-separated values (records need not be one per line).
struct AsciiBody<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// File line of `pos`, and so of the value last read.
    line: u64,
    /// Record of the current element being read.
    record: u64,
    /// Set when a value was wanted and there was none.
    ended: bool,
}

impl<'a> AsciiBody<'a> {
    fn new(bytes: &'a [u8], first_line: u64) -> Self {
        AsciiBody {
            bytes,
            pos: 0,
            line: first_line,
            record: 0,
            ended: false,
        }
    }

    /// The next word, or a "found the end of the file" error.
    fn word(&mut self, expected: &'static str) -> Result<&'a [u8], ParseError> {
        let rest = self.bytes.get(self.pos..).unwrap_or_default();
        let mut start = rest.len();
        for (i, &b) in rest.iter().enumerate() {
            if b == b'\n' {
                self.line += 1;
            } else if !b.is_ascii_whitespace() {
                start = i;
                break;
            }
        }
        let rest = rest.get(start..).unwrap_or_default();
        let len = rest
            .iter()
            .position(u8::is_ascii_whitespace)
            .unwrap_or(rest.len());
        self.pos += start + len;
        match rest.get(..len) {
            Some(word) if !word.is_empty() => Ok(word),
            _ => {
                self.ended = true;
                // The line a final newline would open holds nothing: report the one before.
                if self.bytes.ends_with(b"\n") {
                    self.line = self.line.saturating_sub(1);
                }
                Err(self.syntax(expected, b"the end of the file"))
            }
        }
    }

    fn syntax(&self, expected: &'static str, found: &[u8]) -> ParseError {
        ParseError::at(
            Location::Line(self.line),
            Problem::Syntax {
                expected,
                found: excerpt(found),
            },
        )
    }
}

impl Body for AsciiBody<'_> {
    const IS_TEXT: bool = true;

    fn read_f64(&mut self, _ty: Scalar) -> Result<f64, ParseError> {
        let word = self.word("a number")?;
        std::str::from_utf8(word)
            .ok()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| self.syntax("a number", word))
    }

    fn read_int(&mut self, _ty: Scalar, expected: &'static str) -> Result<i64, ParseError> {
        let word = self.word(expected)?;
        parse_word::<i64>(word)
            .or_else(|| parse_word::<f64>(word).and_then(float_to_int))
            .ok_or_else(|| self.syntax(expected, word))
    }

    fn skip(&mut self, _ty: Scalar, n: u64) -> Result<(), ParseError> {
        for _ in 0..n {
            self.word("a value")?;
        }
        Ok(())
    }

    fn at(&self) -> Location {
        Location::Line(self.line)
    }

    fn start_record(&mut self, record: u64) {
        self.record = record;
    }

    fn ended(&self) -> Option<u64> {
        self.ended.then_some(self.record)
    }
}

/// The lines of the header.
struct HeaderLines<'a> {
    bytes: &'a [u8],
    /// Start of the next line.
    pos: usize,
    /// 1-based number of the line last returned.
    line: u64,
}

impl<'a> Iterator for HeaderLines<'a> {
    type Item = &'a [u8];

    /// The next line, without its `\n` (a `\r` before it is whitespace to the parser).
    fn next(&mut self) -> Option<&'a [u8]> {
        let rest = self.bytes.get(self.pos..).filter(|r| !r.is_empty())?;
        let end = rest.iter().position(|&b| b == b'\n');
        self.pos += end.map_or(rest.len(), |e| e + 1);
        self.line += 1;
        rest.get(..end.unwrap_or(rest.len()))
    }
}

fn trim_end(line: &[u8]) -> &[u8] {
    let end = line
        .iter()
        .rposition(|b| !b.is_ascii_whitespace())
        .map_or(0, |i| i + 1);
    line.get(..end).unwrap_or_default()
}

fn bad_header(line: u64, reason: String) -> ParseError {
    ParseError::at(Location::Line(line), Problem::BadHeader { reason })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A value in a binary body.
    #[derive(Clone, Copy)]
    enum V {
        I8(i8),
        U8(u8),
        I16(i16),
        U16(u16),
        I32(i32),
        U32(u32),
        F32(f32),
        F64(f64),
    }

    /// A binary PLY: the header lines (without `ply`, `format` and `end_header`), then values.
    fn binary(big_endian: bool, header: &str, values: &[V]) -> Vec<u8> {
        let order = if big_endian { "big" } else { "little" };
        let mut out =
            format!("ply\nformat binary_{order}_endian 1.0\n{header}end_header\n").into_bytes();
        for v in values {
            macro_rules! put {
                ($x:expr) => {
                    if big_endian {
                        out.extend_from_slice(&$x.to_be_bytes())
                    } else {
                        out.extend_from_slice(&$x.to_le_bytes())
                    }
                };
            }
            match *v {
                V::I8(x) => put!(x),
                V::U8(x) => put!(x),
                V::I16(x) => put!(x),
                V::U16(x) => put!(x),
                V::I32(x) => put!(x),
                V::U32(x) => put!(x),
                V::F32(x) => put!(x),
                V::F64(x) => put!(x),
            }
        }
        out
    }

    fn read(bytes: &[u8]) -> Result<Soup, ParseError> {
        parse(bytes, &ImportLimits::default())
    }

    fn problem_at(bytes: &[u8]) -> (Option<Location>, Problem) {
        let e = read(bytes).expect_err("the file is malformed");
        (e.at, e.problem)
    }

    fn square() -> Vec<DVec3> {
        vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::Y,
            DVec3::new(0.5, 0.5, 1.0),
        ]
    }

    const ASCII: &str = "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nobj_info none\r\n\
        element vertex 5\r\nproperty float x\r\nproperty float y\r\nproperty float z\r\n\
        element face 2\r\nproperty list uchar int vertex_indices\r\nend_header\r\n\
        0 0 0\r\n1 0 0\r\n1 1 0\r\n0 1 0\r\n0.5 0.5 1\r\n4 0 1 2 3\r\n3 0 1 4\r\n";

    /// Blender 2.4x's banner line has no `comment` before it: the line is skipped and
    /// reported, and the mesh reads as it would without it.
    #[test]
    fn a_header_line_with_an_unknown_keyword_is_skipped_with_a_warning() {
        let with_banner = ASCII.replacen(
            "comment made by hand",
            "Created by Blender3D 247 - www.blender.org, source file: \r\nCreated again",
            1,
        );
        let soup = read(with_banner.as_bytes()).unwrap();
        let plain = read(ASCII.as_bytes()).unwrap();
        assert_eq!(soup.positions, plain.positions);
        assert_eq!(soup.triangles, plain.triangles);
        assert_eq!(
            soup.warnings,
            vec![
                "skipped 2 PLY header line(s) with an unknown keyword (the first: line 3, \
                  \"Created\")"
                    .to_string()
            ]
        );
    }

    #[test]
    fn reads_ascii_with_crlf_and_fans_quads() {
        let soup = read(ASCII.as_bytes()).unwrap();
        assert_eq!(soup.positions, square());
        assert_eq!(soup.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
        assert_eq!(soup.triangulated_polygons, 1);
        assert!(soup.warnings.is_empty());
    }

    /// A header with an unknown element first, extra vertex and face properties (lists
    /// among them), short coordinates, and a signed byte list length.
    const RICH_HEADER: &str = "comment extras everywhere\nelement material 2\n\
        property list uchar float weights\nproperty uint id\n\
        element vertex 5\nproperty uchar red\nproperty short z\nproperty list ushort double extra\n\
        property double x\nproperty float y\n\
        element face 2\nproperty int8 flags\nproperty list int8 uint32 vertex_index\n\
        property list uint8 float texcoord\n\
        element edge 1\nproperty int vertex1\nproperty int vertex2\n";

    fn rich_values() -> Vec<V> {
        let mut v = vec![
            // material: 2 weights and an id; then 0 weights and an id.
            V::U8(2),
            V::F32(0.5),
            V::F32(0.5),
            V::U32(7),
            V::U8(0),
            V::U32(8),
        ];
        for (i, p) in square().iter().enumerate() {
            v.extend([V::U8(255), V::I16(p.z as i16), V::U16(i as u16 % 2)]);
            v.extend((0..i % 2).map(|_| V::F64(9.0)));
            v.extend([V::F64(p.x), V::F32(p.y as f32)]);
        }
        v.extend([
            V::I8(-1),
            V::I8(4),
            V::U32(0),
            V::U32(1),
            V::U32(2),
            V::U32(3),
            V::U8(0),
        ]);
        v.extend([
            V::I8(0),
            V::I8(3),
            V::U32(0),
            V::U32(1),
            V::U32(4),
            V::U8(2),
        ]);
        v.extend([V::F32(0.0), V::F32(1.0)]);
        v.extend([V::I32(0), V::I32(1)]);
        v
    }

    #[test]
    fn reads_binary_of_both_byte_orders_skipping_what_it_does_not_need() {
        for big_endian in [false, true] {
            let soup = read(&binary(big_endian, RICH_HEADER, &rich_values())).unwrap();
            assert_eq!(soup.positions, square(), "big endian: {big_endian}");
            assert_eq!(soup.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
            assert_eq!(soup.triangulated_polygons, 1);
            // The material and edge elements are mentioned.
            assert_eq!(soup.warnings.len(), 2, "{:?}", soup.warnings);
        }
    }

    #[test]
    fn reads_ascii_with_the_same_extras() {
        let body = "2 0.5 0.5 7\n0 8\n\
            255 0 0 0 0\n255 0 1 9 1 0\n255 0 0 1 1\n255 0 1 9 0 1\n255 1 0 0.5 0.5\n\
            -1 4 0 1 2 3 0\n0 3 0 1 4 2 0 1\n0 1\n";
        let text = format!("ply\nformat ascii 1.0\n{RICH_HEADER}end_header\n{body}");
        let soup = read(text.as_bytes()).unwrap();
        assert_eq!(soup.positions, square());
        assert_eq!(soup.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
    }

    #[test]
    fn reads_faces_declared_before_vertices() {
        let header = "element face 1\nproperty list uchar int vertex_indices\n\
            element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
        let mut values = vec![V::U8(3), V::I32(2), V::I32(1), V::I32(0)];
        for p in [DVec3::ZERO, DVec3::X, DVec3::Y] {
            values.extend([V::F32(p.x as f32), V::F32(p.y as f32), V::F32(p.z as f32)]);
        }
        let soup = read(&binary(false, header, &values)).unwrap();
        assert_eq!(soup.positions, vec![DVec3::ZERO, DVec3::X, DVec3::Y]);
        assert_eq!(soup.triangles, vec![[2, 1, 0]]);
    }

    #[test]
    fn skips_elements_without_properties_at_once() {
        let header = format!("element nothing 18446744073709551615\n{TRIANGLE_HEADER}");
        let text =
            format!("ply\nformat ascii 1.0\n{header}end_header\n0 0 0 1 0 0 0 1 0 3 0 1 2\n");
        assert_eq!(read(text.as_bytes()).unwrap().triangles, vec![[0, 1, 2]]);
        let bytes = binary(true, &header, &triangle_values(&[0, 1, 2]));
        assert_eq!(read(&bytes).unwrap().triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn reads_a_point_cloud_as_no_triangles() {
        let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
            property float y\nproperty float z\nend_header\n1 2 3\n";
        let soup = read(text.as_bytes()).unwrap();
        assert_eq!(soup.positions, vec![DVec3::new(1.0, 2.0, 3.0)]);
        assert!(soup.triangles.is_empty());
    }

    #[test]
    fn reports_empty_and_foreign_files() {
        assert_eq!(problem_at(b""), (None, Problem::Empty));
        let not_ply = Problem::NotThisFormat { expected: "PLY" };
        assert_eq!(problem_at(b"OFF\n3 1 0\n"), (None, not_ply.clone()));
        assert_eq!(problem_at(b"plywood\n"), (None, not_ply));
    }

    #[test]
    fn reports_bad_headers_with_their_line() {
        let bad = |text: &str| match problem_at(text.as_bytes()) {
            (Some(Location::Line(n)), Problem::BadHeader { .. }) => n,
            other => panic!("{text:?}: {other:?}"),
        };
        let xyz = "property float x\nproperty float y\nproperty float z\n";
        // No end_header: the last line.
        assert_eq!(
            bad(&format!("ply\nformat ascii 1.0\nelement vertex 1\n{xyz}")),
            6
        );
        assert_eq!(bad("ply\nformat ascii 1.0\nend_header\n"), 3);
        assert_eq!(
            bad("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n"),
            3
        );
        assert_eq!(bad(&format!("ply\nelement vertex 1\n{xyz}end_header\n")), 6);
        assert_eq!(bad(&format!("ply\nformat ascii 1.0\nelement vertex 1\n{xyz}element face 1\nproperty int vertex_indices\nend_header\n")), 7);
        assert_eq!(
            bad(&format!(
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty flaot w\n{xyz}end_header\n"
            )),
            4
        );
        assert_eq!(
            bad(&format!(
                "ply\nformat ascii 1.0\nproperty float x\nelement vertex 1\n{xyz}end_header\n"
            )),
            3
        );
        assert_eq!(
            bad(&format!(
                "ply\nformat ascii 1.0\nelement vertex -1\n{xyz}end_header\n"
            )),
            3
        );
        assert_eq!(
            bad(&format!(
                "ply\nformat ascii 1.0\nelemnet vertex 1\n{xyz}end_header\n"
            )),
            3
        );
        assert_eq!(
            bad(&format!(
                "ply\nformat binary_middle_endian 1.0\nelement vertex 1\n{xyz}end_header\n"
            )),
            2
        );
        assert!(matches!(
            problem_at(
                format!("ply\nformat ascii 2.0\nelement vertex 1\n{xyz}end_header\n").as_bytes()
            ),
            (Some(Location::Line(2)), Problem::Unsupported { .. })
        ));
    }

    const TRIANGLE_HEADER: &str = "element vertex 3\nproperty float x\nproperty float y\n\
        property float z\nelement face 1\nproperty list uchar int vertex_indices\n";
    /// Bytes before the body of `binary(big_endian, TRIANGLE_HEADER, _)`.
    fn triangle_body_start(big_endian: bool) -> u64 {
        binary(big_endian, TRIANGLE_HEADER, &[]).len() as u64
    }

    fn triangle_values(face: &[i32]) -> Vec<V> {
        let mut v = Vec::new();
        for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            v.extend(p.map(V::F32));
        }
        v.push(V::U8(face.len() as u8));
        v.extend(face.iter().map(|&i| V::I32(i)));
        v
    }

    #[test]
    fn locates_binary_problems_by_byte() {
        let start = triangle_body_start(false);
        let good = binary(false, TRIANGLE_HEADER, &triangle_values(&[0, 1, 2]));
        assert_eq!(good.len() as u64, start + 36 + 13);
        assert_eq!(read(&good).unwrap().triangles, vec![[0, 1, 2]]);

        // The last index is cut short.
        assert_eq!(
            problem_at(&good[..good.len() - 1]),
            (
                Some(Location::Byte(start + 36 + 9)),
                Problem::Truncated {
                    needed: 4,
                    available: 3
                }
            )
        );
        let mut values = triangle_values(&[0, 1, 2]);
        values[4] = V::F32(f32::NAN);
        assert_eq!(
            problem_at(&binary(true, TRIANGLE_HEADER, &values)),
            (
                Some(Location::Byte(triangle_body_start(true) + 16)),
                Problem::NonFiniteCoordinate { vertex: 1 }
            )
        );
        assert_eq!(
            problem_at(&binary(
                false,
                TRIANGLE_HEADER,
                &triangle_values(&[0, 3, 2])
            )),
            (
                Some(Location::Byte(start + 36 + 5)),
                Problem::IndexOutOfRange {
                    index: 3,
                    vertex_count: 3
                }
            )
        );
        assert_eq!(
            problem_at(&binary(
                false,
                TRIANGLE_HEADER,
                &triangle_values(&[0, -1, 2])
            ))
            .1,
            Problem::IndexOutOfRange {
                index: -1,
                vertex_count: 3
            }
        );
        assert_eq!(
            problem_at(&binary(false, TRIANGLE_HEADER, &triangle_values(&[0, 1]))),
            (
                Some(Location::Byte(start + 36)),
                Problem::FaceTooSmall { vertices: 2 }
            )
        );
    }

    fn ascii_triangle(body: &str) -> String {
        format!("ply\nformat ascii 1.0\n{TRIANGLE_HEADER}end_header\n{body}")
    }

    #[test]
    fn locates_ascii_problems_by_line() {
        // The header is 9 lines; the body starts on line 10.
        let good = read(ascii_triangle("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").as_bytes()).unwrap();
        assert_eq!(good.triangles, vec![[0, 1, 2]]);
        assert_eq!(
            problem_at(ascii_triangle("0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n").as_bytes()),
            (
                Some(Location::Line(11)),
                Problem::NonFiniteCoordinate { vertex: 1 }
            )
        );
        assert_eq!(
            problem_at(ascii_triangle("0 0 0\n1 0 0\n0 one 0\n3 0 1 2\n").as_bytes()),
            (
                Some(Location::Line(12)),
                Problem::Syntax {
                    expected: "a number",
                    found: "one".into()
                }
            )
        );
        assert_eq!(
            problem_at(ascii_triangle("0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n").as_bytes()),
            (
                Some(Location::Line(13)),
                Problem::IndexOutOfRange {
                    index: 7,
                    vertex_count: 3
                }
            )
        );
        assert_eq!(
            problem_at(ascii_triangle("0 0 0\n1 0 0\n0 1 0\n1 0    \n").as_bytes()),
            (
                Some(Location::Line(13)),
                Problem::FaceTooSmall { vertices: 1 }
            )
        );
        assert_eq!(
            problem_at(ascii_triangle("0 0 0\n1 0 0\n0 1 0\n3 0 1\n\n").as_bytes()),
            (
                Some(Location::Line(14)),
                Problem::CountMismatch {
                    what: "faces",
                    declared: 1,
                    found: 0
                }
            )
        );
        assert_eq!(
            problem_at(ascii_triangle("0 0 0\n1 0 0\n0 1\n       \n      \n").as_bytes()),
            (
                Some(Location::Line(14)),
                Problem::CountMismatch {
                    what: "vertices",
                    declared: 3,
                    found: 2
                }
            )
        );
    }

    #[test]
    fn checks_forged_counts_before_allocating() {
        let forged = |count: &str, big: bool| {
            let header = TRIANGLE_HEADER.replace("vertex 3", &format!("vertex {count}"));
            problem_at(&binary(big, &header, &triangle_values(&[0, 1, 2])))
        };
        assert_eq!(
            forged("4000000000", false),
            (
                Some(Location::Line(3)),
                Problem::LimitsExceeded {
                    what: "vertices",
                    requested: 4_000_000_000,
                    max: 1 << 27
                }
            )
        );
        // "vertex 1000000" is 6 bytes longer than "vertex 3".
        assert_eq!(
            forged("1000000", true),
            (
                Some(Location::Byte(triangle_body_start(true) + 6)),
                Problem::Truncated {
                    needed: 12_000_000,
                    available: 49
                }
            )
        );
        // An unknown element's count is checked against the bytes too.
        let header = format!("element junk 99999999999\nproperty double a\n{TRIANGLE_HEADER}");
        let bytes = binary(false, &header, &triangle_values(&[0, 1, 2]));
        assert_eq!(
            problem_at(&bytes),
            (
                Some(Location::Byte(bytes.len() as u64 - 49)),
                Problem::Truncated {
                    needed: 799_999_999_992,
                    available: 49
                }
            )
        );
        let text = ascii_triangle("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").replace("face 1", "face 1000");
        assert_eq!(
            problem_at(text.as_bytes()),
            (
                Some(Location::Line(7)),
                Problem::Truncated {
                    needed: 2000,
                    // 26 body bytes, one for the missing last separator, 18 for the vertices.
                    available: 9
                }
            )
        );
        let tight = ImportLimits {
            max_faces: 1,
            ..ImportLimits::default()
        };
        assert_eq!(
            parse(ASCII.as_bytes(), &tight).unwrap_err().problem,
            Problem::LimitsExceeded {
                what: "faces",
                requested: 2,
                max: 1
            }
        );
    }
}
