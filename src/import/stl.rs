//! STL reader, binary and ASCII.
//!
//! Binary STL is an 80-byte header, a little-endian `u32` facet count, then 50 bytes per
//! facet: a normal and three vertices as 12 little-endian `f32`s and a `u16` attribute.
//! ASCII STL is
//!
//! ```text
//! solid [name]
//!   facet normal nx ny nz
//!     outer loop
//!       vertex x y z      (three times)
//!     endloop
//!   endfacet
//! endsolid [name]
//! ```
//!
//! possibly several solids in a row, keywords in any case.
//!
//! Many binary files also begin with `solid`, so the choice goes: a file whose length is
//! exactly `84 + 50 × count` is binary; otherwise one that begins with `solid` is ASCII, unless
//! it fails as ASCII and holds bytes that are not text; any other file is binary unless it is
//! all text. Bytes after the last binary facet are ignored with a warning.
//!
//! STL has no shared vertices: each facet adds three vertices of its own (normals are
//! ignored), and [`repair`](super::repair) welds them.

use super::{check_limit, excerpt, ImportLimits, Location, ParseError, Problem, Soup};
use glam::DVec3;

/// Bytes before the first binary facet: the header and the facet count.
const BINARY_HEADER_BYTES: u64 = 84;
/// Byte offset of the binary facet count.
const BINARY_COUNT_OFFSET: u64 = 80;
/// Bytes per binary facet: 12 `f32`s and a `u16`.
const BINARY_FACET_BYTES: u64 = 50;
/// Byte offset of the first vertex within a binary facet (after the normal).
const BINARY_VERTICES_OFFSET: usize = 12;

/// Parses an STL file.
pub(crate) fn parse(bytes: &[u8], limits: &ImportLimits) -> Result<Soup, ParseError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(ParseError::whole(Problem::Empty));
    }
    let len = bytes.len() as u64;
    let binary_len =
        binary_facet_count(bytes).map(|n| BINARY_HEADER_BYTES + BINARY_FACET_BYTES * u64::from(n));
    if binary_len == Some(len) {
        return read_binary(bytes, limits);
    }
    if begins_with_solid(bytes) {
        return read_ascii(bytes, limits).or_else(|ascii_error| {
            // A binary file whose header begins with "solid" but whose length is off.
            if binary_len.is_some() && !is_text(bytes) {
                read_binary(bytes, limits)
            } else {
                Err(ascii_error)
            }
        });
    }
    // Text that is not ASCII STL (and not by chance exactly the length of a binary one).
    if is_text(bytes) {
        return Err(ParseError::whole(Problem::NotThisFormat {
            expected: "STL",
        }));
    }
    read_binary(bytes, limits)
}

/// Whether every byte is printable ASCII or whitespace.
fn is_text(bytes: &[u8]) -> bool {
    bytes
        .iter()
        .all(|b| b.is_ascii_graphic() || b.is_ascii_whitespace())
}

/// The facet count of a binary STL, if the file is long enough to hold one.
fn binary_facet_count(bytes: &[u8]) -> Option<u32> {
    let start = BINARY_COUNT_OFFSET as usize;
    let count = bytes.get(start..start + 4)?;
    Some(u32::from_le_bytes(count.try_into().ok()?))
}

/// Whether the first word of the file is `solid` (after an optional byte-order mark).
fn begins_with_solid(bytes: &[u8]) -> bool {
    let mut tokens = Tokens::new(bytes);
    tokens
        .next()
        .is_some_and(|t| t.eq_ignore_ascii_case(b"solid"))
}

/// Reads a binary STL.
fn read_binary(bytes: &[u8], limits: &ImportLimits) -> Result<Soup, ParseError> {
    let len = bytes.len() as u64;
    let Some(count) = binary_facet_count(bytes) else {
        return Err(ParseError::at(
            Location::Byte(0),
            Problem::Truncated {
                needed: BINARY_HEADER_BYTES,
                available: len,
            },
        ));
    };
    let count = u64::from(count);
    let at_count = Location::Byte(BINARY_COUNT_OFFSET);
    check_limit("triangles", count, limits.max_faces).map_err(|p| ParseError::at(at_count, p))?;
    let vertex_limit = limits.max_vertices.min(u64::from(u32::MAX));
    check_limit("vertices", 3 * count, vertex_limit).map_err(|p| ParseError::at(at_count, p))?;
    let needed = BINARY_FACET_BYTES * count;
    let available = len - BINARY_HEADER_BYTES;
    if needed > available {
        return Err(ParseError::at(
            Location::Byte(BINARY_HEADER_BYTES),
            Problem::Truncated { needed, available },
        ));
    }

    // `count` facets fit in the file, so these allocations are bounded by its length.
    let facets = bytes
        .get(BINARY_HEADER_BYTES as usize..(BINARY_HEADER_BYTES + needed) as usize)
        .unwrap_or_default();
    let mut soup = Soup {
        positions: Vec::with_capacity(3 * facets.len() / 50),
        triangles: Vec::with_capacity(facets.len() / 50),
        ..Soup::default()
    };
    for (facet, record) in facets.chunks_exact(BINARY_FACET_BYTES as usize).enumerate() {
        let facet_start = BINARY_HEADER_BYTES + BINARY_FACET_BYTES * facet as u64;
        let first = soup.positions.len() as u32;
        for corner in 0..3 {
            let mut p = [0.0; 3];
            for (axis, c) in p.iter_mut().enumerate() {
                let offset = BINARY_VERTICES_OFFSET + 12 * corner + 4 * axis;
                let value = record
                    .get(offset..offset + 4)
                    .and_then(|b| b.try_into().ok())
                    .map(f32::from_le_bytes)
                    .unwrap_or(f32::NAN);
                if !value.is_finite() {
                    return Err(ParseError::at(
                        Location::Byte(facet_start + offset as u64),
                        Problem::NonFiniteCoordinate {
                            vertex: soup.positions.len() as u64,
                        },
                    ));
                }
                *c = f64::from(value);
            }
            soup.positions.push(DVec3::from_array(p));
        }
        soup.triangles.push([first, first + 1, first + 2]);
    }
    let trailing = available - needed;
    if trailing > 0 {
        soup.warnings.push(format!(
            "ignored {trailing} bytes after the last of {count} binary STL facets"
        ));
    }
    Ok(soup)
}

/// Reads an ASCII STL: one or more `solid … endsolid` blocks.
fn read_ascii(bytes: &[u8], limits: &ImportLimits) -> Result<Soup, ParseError> {
    let mut reader = AsciiReader {
        tokens: Tokens::new(bytes),
        soup: Soup::default(),
        max_vertices: limits.max_vertices.min(u64::from(u32::MAX)),
        max_triangles: limits.max_faces,
    };
    while let Some(word) = reader.tokens.next() {
        if !word.eq_ignore_ascii_case(b"solid") {
            return Err(reader.syntax("solid", word));
        }
        reader.tokens.skip_line(); // the solid's name
        reader.read_solid()?;
    }
    Ok(reader.soup)
}

/// State of the ASCII STL parse.
struct AsciiReader<'a> {
    tokens: Tokens<'a>,
    soup: Soup,
    max_vertices: u64,
    max_triangles: u64,
}

impl<'a> AsciiReader<'a> {
    /// Reads facets up to and including `endsolid`.
    fn read_solid(&mut self) -> Result<(), ParseError> {
        loop {
            let word = self.next_word("facet or endsolid")?;
            if word.eq_ignore_ascii_case(b"endsolid") {
                self.tokens.skip_line(); // the solid's name
                return Ok(());
            }
            if !word.eq_ignore_ascii_case(b"facet") {
                return Err(self.syntax("facet or endsolid", word));
            }
            self.read_facet()?;
        }
    }

    /// Reads a facet after its `facet` keyword, up to and including `endfacet`.
    fn read_facet(&mut self) -> Result<(), ParseError> {
        let facet_line = Location::Line(self.tokens.line);
        self.expect("normal")?;
        for _ in 0..3 {
            // Normals are ignored, but must be numbers (NaN is tolerated: nobody reads it).
            self.read_number("a normal component")?;
        }
        self.expect("outer")?;
        self.expect("loop")?;
        let first = self.soup.positions.len() as u64;
        loop {
            let word = self.next_word("vertex or endloop")?;
            if word.eq_ignore_ascii_case(b"endloop") {
                break;
            }
            if !word.eq_ignore_ascii_case(b"vertex") {
                return Err(self.syntax("vertex or endloop", word));
            }
            self.read_vertex()?;
        }
        let corners = self.soup.positions.len() as u64 - first;
        if corners < 3 {
            return Err(ParseError::at(
                facet_line,
                Problem::FaceTooSmall { vertices: corners },
            ));
        }
        // Indices are below `max_vertices` ≤ u32::MAX, checked as each vertex was added.
        let first = first as u32;
        for k in 1..corners as u32 - 1 {
            if self.soup.triangles.len() as u64 >= self.max_triangles {
                return Err(ParseError::at(
                    facet_line,
                    Problem::LimitsExceeded {
                        what: "triangles",
                        requested: self.soup.triangles.len() as u64 + 1,
                        max: self.max_triangles,
                    },
                ));
            }
            self.soup.triangles.push([first, first + k, first + k + 1]);
        }
        if corners > 3 {
            self.soup.triangulated_polygons += 1;
        }
        self.expect("endfacet")
    }

    /// Reads the coordinates after a `vertex` keyword.
    fn read_vertex(&mut self) -> Result<(), ParseError> {
        let vertex = self.soup.positions.len() as u64;
        if vertex >= self.max_vertices {
            return Err(ParseError::at(
                Location::Line(self.tokens.line),
                Problem::LimitsExceeded {
                    what: "vertices",
                    requested: vertex + 1,
                    max: self.max_vertices,
                },
            ));
        }
        let mut p = [0.0; 3];
        for c in &mut p {
            *c = self.read_number("a coordinate")?;
        }
        let p = DVec3::from_array(p);
        if !p.is_finite() {
            return Err(ParseError::at(
                Location::Line(self.tokens.line),
                Problem::NonFiniteCoordinate { vertex },
            ));
        }
        self.soup.positions.push(p);
        Ok(())
    }

    /// Reads a number (possibly NaN or infinite).
    fn read_number(&mut self, expected: &'static str) -> Result<f64, ParseError> {
        let word = self.next_word(expected)?;
        std::str::from_utf8(word)
            .ok()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| self.syntax(expected, word))
    }

    /// Reads a keyword.
    fn expect(&mut self, keyword: &'static str) -> Result<(), ParseError> {
        let word = self.next_word(keyword)?;
        if word.eq_ignore_ascii_case(keyword.as_bytes()) {
            Ok(())
        } else {
            Err(self.syntax(keyword, word))
        }
    }

    /// The next word, which must exist.
    fn next_word(&mut self, expected: &'static str) -> Result<&'a [u8], ParseError> {
        self.tokens.next().ok_or_else(|| {
            // The line a final newline would open holds nothing: report the one before.
            let line = match self.tokens.bytes.last() {
                Some(b'\n') => self.tokens.line.saturating_sub(1).max(1),
                _ => self.tokens.line,
            };
            ParseError::at(
                Location::Line(line),
                Problem::Syntax {
                    expected,
                    found: "the end of the file".into(),
                },
            )
        })
    }

    /// A syntax error at the current line.
    fn syntax(&self, expected: &'static str, found: &[u8]) -> ParseError {
        ParseError::at(
            Location::Line(self.tokens.line),
            Problem::Syntax {
                expected,
                found: excerpt(found),
            },
        )
    }
}

/// Whitespace-separated words of a text, with the line each is on.
struct Tokens<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// 1-based line of `pos` (and so of the word last returned).
    line: u64,
}

impl<'a> Tokens<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Tokens {
            bytes: bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes),
            pos: 0,
            line: 1,
        }
    }

    /// The next word, or `None` at the end.
    fn next(&mut self) -> Option<&'a [u8]> {
        let rest = self.bytes.get(self.pos..)?;
        let mut start = rest.len();
        for (i, &b) in rest.iter().enumerate() {
            if b == b'\n' {
                self.line += 1;
            } else if !b.is_ascii_whitespace() {
                start = i;
                break;
            }
        }
        let rest = rest.get(start..)?;
        let len = rest
            .iter()
            .position(u8::is_ascii_whitespace)
            .unwrap_or(rest.len());
        self.pos += start + len;
        rest.get(..len).filter(|w| !w.is_empty())
    }

    /// Skips to the start of the next line.
    fn skip_line(&mut self) {
        let rest = self.bytes.get(self.pos..).unwrap_or_default();
        match rest.iter().position(|&b| b == b'\n') {
            Some(newline) => {
                self.pos += newline + 1;
                self.line += 1;
            }
            None => self.pos = self.bytes.len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regular-ish tetrahedron's four faces, outward.
    const TETRA: [[[f32; 3]; 3]; 4] = [
        [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    ];

    /// A binary STL of `facets`, with a header that begins with `header`.
    fn binary(header: &[u8], facets: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut out = vec![b' '; 80];
        out[..header.len()].copy_from_slice(header);
        out.extend_from_slice(&(facets.len() as u32).to_le_bytes());
        for facet in facets {
            out.extend_from_slice(&[0; 12]);
            for c in facet.iter().flatten() {
                out.extend_from_slice(&c.to_le_bytes());
            }
            out.extend_from_slice(&[0; 2]);
        }
        out
    }

    fn ascii(facets: &[[[f32; 3]; 3]]) -> String {
        let mut out = String::from("solid tetra\n");
        for facet in facets {
            out += "  facet normal 0 0 0\n    outer loop\n";
            for v in facet {
                out += &format!("      vertex {} {} {}\n", v[0], v[1], v[2]);
            }
            out += "    endloop\n  endfacet\n";
        }
        out + "endsolid tetra\n"
    }

    fn read(bytes: &[u8]) -> Result<Soup, ParseError> {
        parse(bytes, &ImportLimits::default())
    }

    fn problem_at(bytes: &[u8]) -> (Option<Location>, Problem) {
        let e = read(bytes).expect_err("the file is malformed");
        (e.at, e.problem)
    }

    fn assert_is_tetra(soup: &Soup) {
        assert_eq!(soup.positions.len(), 12);
        assert_eq!(soup.triangles.len(), 4);
        for (f, facet) in TETRA.iter().enumerate() {
            assert_eq!(
                soup.triangles[f],
                [3 * f as u32, 3 * f as u32 + 1, 3 * f as u32 + 2]
            );
            for (c, v) in facet.iter().enumerate() {
                let p = soup.positions[3 * f + c];
                assert_eq!(p, DVec3::new(v[0].into(), v[1].into(), v[2].into()));
            }
        }
    }

    #[test]
    fn reads_binary_even_when_the_header_says_solid() {
        assert_is_tetra(&read(&binary(b"binary", &TETRA)).unwrap());
        assert_is_tetra(&read(&binary(b"solid tetra", &TETRA)).unwrap());
    }

    #[test]
    fn reads_binary_with_trailing_bytes_and_warns() {
        let mut bytes = binary(b"solid tetra", &TETRA);
        bytes.extend_from_slice(&[0, 0, 0]);
        let soup = read(&bytes).unwrap();
        assert_is_tetra(&soup);
        assert_eq!(soup.warnings.len(), 1);
    }

    #[test]
    fn reads_ascii_with_crlf_upper_case_and_several_solids() {
        assert_is_tetra(&read(ascii(&TETRA).as_bytes()).unwrap());
        let two = ascii(&TETRA[..2]) + &ascii(&TETRA[2..]);
        let two = two.replace('\n', "\r\n").replace("vertex", "VERTEX");
        assert_is_tetra(&read(two.as_bytes()).unwrap());
    }

    #[test]
    fn fans_ascii_polygons() {
        let text = "solid q\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n\
                    vertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid q\n";
        let soup = read(text.as_bytes()).unwrap();
        assert_eq!(soup.positions.len(), 4);
        assert_eq!(soup.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(soup.triangulated_polygons, 1);
    }

    #[test]
    fn reports_empty_and_foreign_files() {
        assert_eq!(problem_at(b""), (None, Problem::Empty));
        assert_eq!(problem_at(b" \r\n\t"), (None, Problem::Empty));
        for text in ["hello, world\n".to_string(), "hello, world\n".repeat(20)] {
            assert_eq!(
                problem_at(text.as_bytes()),
                (None, Problem::NotThisFormat { expected: "STL" })
            );
        }
        assert_eq!(
            problem_at(b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 zero 0\n"),
            (
                Some(Location::Line(4)),
                Problem::Syntax {
                    expected: "a coordinate",
                    found: "zero".into()
                }
            )
        );
    }

    #[test]
    fn reports_truncated_files() {
        let bytes = binary(b"bin", &TETRA);
        assert_eq!(
            problem_at(&bytes[..bytes.len() - 1]),
            (
                Some(Location::Byte(84)),
                Problem::Truncated {
                    needed: 200,
                    available: 199
                }
            )
        );
        // Binary content after a "solid" header: the binary reading's error is the one reported.
        let bytes = binary(b"solid", &TETRA);
        assert_eq!(
            problem_at(&bytes[..150]).1,
            Problem::Truncated {
                needed: 200,
                available: 66
            }
        );
        assert_eq!(
            problem_at(&binary(b"\0bin", &TETRA)[..40]),
            (
                Some(Location::Byte(0)),
                Problem::Truncated {
                    needed: 84,
                    available: 40
                }
            )
        );
        // A final newline does not open a line of its own: the file ends on line 8.
        let text = ascii(&TETRA[..1]).replace("endsolid tetra\n", "");
        assert_eq!(
            problem_at(text.as_bytes()),
            (
                Some(Location::Line(8)),
                Problem::Syntax {
                    expected: "facet or endsolid",
                    found: "the end of the file".into()
                }
            )
        );
        let text = ascii(&TETRA);
        // Cut after "endloop\n  ", so the file ends on line 8.
        let cut = &text[..text.find("endfacet").unwrap()];
        assert_eq!(
            problem_at(cut.as_bytes()),
            (
                Some(Location::Line(8)),
                Problem::Syntax {
                    expected: "endfacet",
                    found: "the end of the file".into()
                }
            )
        );
    }

    #[test]
    fn reports_non_finite_coordinates_where_they_are() {
        let mut facets = TETRA;
        facets[1][2][1] = f32::INFINITY;
        // Facet 1 starts at 84 + 50; its vertex 2 at + 12 + 24; y at + 4.
        assert_eq!(
            problem_at(&binary(b"", &facets)),
            (
                Some(Location::Byte(84 + 50 + 12 + 24 + 4)),
                Problem::NonFiniteCoordinate { vertex: 5 }
            )
        );
        let text = ascii(&TETRA).replacen("vertex 1 0 0", "vertex 1 nan 0", 1);
        assert_eq!(
            problem_at(text.as_bytes()),
            (
                Some(Location::Line(6)),
                Problem::NonFiniteCoordinate { vertex: 2 }
            )
        );
    }

    #[test]
    fn reports_loops_of_fewer_than_three_vertices() {
        let text = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n\
                    endloop\nendfacet\nendsolid x\n";
        assert_eq!(
            problem_at(text.as_bytes()),
            (
                Some(Location::Line(2)),
                Problem::FaceTooSmall { vertices: 2 }
            )
        );
    }

    #[test]
    fn checks_forged_counts_before_allocating() {
        let mut bytes = binary(b"", &TETRA);
        bytes[80..84].copy_from_slice(&4_000_000_000u32.to_le_bytes());
        assert_eq!(
            problem_at(&bytes),
            (
                Some(Location::Byte(80)),
                Problem::LimitsExceeded {
                    what: "triangles",
                    requested: 4_000_000_000,
                    max: 1 << 27
                }
            )
        );
        bytes[80..84].copy_from_slice(&10_000_000u32.to_le_bytes());
        assert_eq!(
            problem_at(&bytes),
            (
                Some(Location::Byte(84)),
                Problem::Truncated {
                    needed: 500_000_000,
                    available: 200
                }
            )
        );
        let tight = ImportLimits {
            max_vertices: 11,
            ..ImportLimits::default()
        };
        assert!(matches!(
            parse(&binary(b"", &TETRA), &tight).unwrap_err().problem,
            Problem::LimitsExceeded {
                what: "vertices",
                ..
            }
        ));
        assert!(matches!(
            parse(ascii(&TETRA).as_bytes(), &tight).unwrap_err().problem,
            Problem::LimitsExceeded {
                what: "vertices",
                ..
            }
        ));
    }
}
