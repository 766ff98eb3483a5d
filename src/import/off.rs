//! OFF reader (Geomview's Object File Format).
//!
//! ```text
//! [ST][C][N]OFF          header keyword; ST, C, N add texture, colour, normal values per vertex
//! nv nf ne               counts (on the keyword's line or the next); ne is ignored
//! x y z [extras…]        nv vertex lines
//! n i0 … i(n-1) [colour] nf face lines; polygons are fanned into triangles
//! ```
//!
//! `#` starts a comment anywhere. Every record is one line: the values a record needs must be
//! on its line, and anything after them (per-vertex extras, per-face colours) is skipped, so
//! every colour convention in the wild reads the same. Counts are checked against the limits
//! and the bytes left before anything is allocated.

use super::{check_limit, excerpt, parse_word, ImportLimits, Location, ParseError, Problem, Soup};
use glam::DVec3;

/// Fewest bytes a vertex line can take (`0 0 0\n`).
const MIN_VERTEX_BYTES: u64 = 6;
/// Fewest bytes a face line can take (`0\n`, which is an error, but reported as such).
const MIN_FACE_BYTES: u64 = 2;

/// Parses an OFF file.
pub(crate) fn parse(bytes: &[u8], limits: &ImportLimits) -> Result<Soup, ParseError> {
    let mut lines = Lines::new(bytes);
    let Some(mut first) = lines.next_record() else {
        return Err(ParseError::whole(Problem::Empty));
    };
    let keyword = first.next().unwrap_or_default();
    read_keyword(keyword).map_err(|p| ParseError::at(Location::Line(lines.line), p))?;

    let (vertex_count, face_count) = read_counts(&mut lines, first)?;
    let counts_line = Location::Line(lines.line);
    let vertex_limit = limits.max_vertices.min(u64::from(u32::MAX));
    check_limit("vertices", vertex_count, vertex_limit)
        .map_err(|p| ParseError::at(counts_line, p))?;
    check_limit("faces", face_count, limits.max_faces)
        .map_err(|p| ParseError::at(counts_line, p))?;
    let left = lines.bytes_left();
    let needed = vertex_count
        .saturating_mul(MIN_VERTEX_BYTES)
        .saturating_add(face_count.saturating_mul(MIN_FACE_BYTES))
        // The last line needs no newline.
        .saturating_sub(1);
    if needed > left {
        return Err(ParseError::at(
            counts_line,
            Problem::Truncated {
                needed,
                available: left,
            },
        ));
    }

    // Both counts are now bounded by the file's length, so these fit in memory.
    let mut soup = Soup {
        positions: Vec::with_capacity(to_usize(vertex_count)),
        triangles: Vec::with_capacity(to_usize(face_count)),
        ..Soup::default()
    };
    read_vertices(&mut lines, vertex_count, &mut soup)?;
    read_faces(&mut lines, face_count, limits.max_faces, &mut soup)?;
    Ok(soup)
}

/// Checks the header keyword: `OFF` with optional `ST`, `C` and `N` prefixes in that order.
fn read_keyword(keyword: &[u8]) -> Result<(), Problem> {
    let Some(prefix) = keyword.strip_suffix(b"OFF") else {
        return Err(Problem::NotThisFormat { expected: "OFF" });
    };
    let mut rest = prefix;
    for part in [&b"ST"[..], b"C", b"N"] {
        rest = rest.strip_prefix(part).unwrap_or(rest);
    }
    match rest {
        [] => Ok(()),
        b"4" | b"n" | b"4n" => Err(Problem::Unsupported {
            what: format!(
                "{} (OFF with other than three dimensions)",
                excerpt(keyword)
            ),
        }),
        _ => Err(Problem::NotThisFormat { expected: "OFF" }),
    }
}

/// Reads the vertex and face counts, from the rest of the keyword line or the next record.
fn read_counts<'a>(lines: &mut Lines<'a>, rest: Words<'a>) -> Result<(u64, u64), ParseError> {
    let mut words = match rest.clone().next() {
        Some(b"BINARY") => {
            return Err(ParseError::at(
                Location::Line(lines.line),
                Problem::Unsupported {
                    what: "binary OFF".into(),
                },
            ))
        }
        Some(_) => rest,
        None => lines.next_record().ok_or_else(|| {
            ParseError::at(
                Location::Line(lines.line),
                Problem::Syntax {
                    expected: "the vertex and face counts",
                    found: "end of file".into(),
                },
            )
        })?,
    };
    let at = Location::Line(lines.line);
    let vertex_count = read_count(words.next(), "the vertex count", at)?;
    let face_count = read_count(words.next(), "the face count", at)?;
    // The edge count, if present, is ignored.
    Ok((vertex_count, face_count))
}

/// Reads a non-negative count.
fn read_count(
    word: Option<&[u8]>,
    expected: &'static str,
    at: Location,
) -> Result<u64, ParseError> {
    let word = word.unwrap_or_default();
    parse_word::<u64>(word).ok_or_else(|| {
        ParseError::at(
            at,
            Problem::Syntax {
                expected,
                found: excerpt(word),
            },
        )
    })
}

/// Reads `count` vertex lines into `soup.positions`.
fn read_vertices(lines: &mut Lines<'_>, count: u64, soup: &mut Soup) -> Result<(), ParseError> {
    for vertex in 0..count {
        let Some(mut words) = lines.next_record() else {
            return Err(ParseError::at(
                Location::Line(lines.line),
                Problem::CountMismatch {
                    what: "vertices",
                    declared: count,
                    found: vertex,
                },
            ));
        };
        let at = Location::Line(lines.line);
        let mut p = [0.0; 3];
        for c in &mut p {
            let word = words.next().unwrap_or_default();
            *c = parse_word::<f64>(word).ok_or_else(|| {
                ParseError::at(
                    at,
                    Problem::Syntax {
                        expected: "a coordinate",
                        found: excerpt(word),
                    },
                )
            })?;
        }
        let p = DVec3::from_array(p);
        if !p.is_finite() {
            return Err(ParseError::at(at, Problem::NonFiniteCoordinate { vertex }));
        }
        soup.positions.push(p);
    }
    Ok(())
}

/// Reads `count` face lines into `soup.triangles`, fanning polygons.
fn read_faces(
    lines: &mut Lines<'_>,
    count: u64,
    max_triangles: u64,
    soup: &mut Soup,
) -> Result<(), ParseError> {
    let vertex_count = soup.positions.len() as u64;
    for face in 0..count {
        let Some(mut words) = lines.next_record() else {
            return Err(ParseError::at(
                Location::Line(lines.line),
                Problem::CountMismatch {
                    what: "faces",
                    declared: count,
                    found: face,
                },
            ));
        };
        let at = Location::Line(lines.line);
        let word = words.next().unwrap_or_default();
        let n = parse_word::<u64>(word).ok_or_else(|| {
            ParseError::at(
                at,
                Problem::Syntax {
                    expected: "a face's vertex count",
                    found: excerpt(word),
                },
            )
        })?;
        if n < 3 {
            return Err(ParseError::at(at, Problem::FaceTooSmall { vertices: n }));
        }
        let mut read_index = || -> Result<u32, ParseError> {
            let word = words.next().unwrap_or_default();
            let index = parse_word::<i64>(word).ok_or_else(|| {
                ParseError::at(
                    at,
                    Problem::Syntax {
                        expected: "a vertex index",
                        found: excerpt(word),
                    },
                )
            })?;
            u32::try_from(index)
                .ok()
                .filter(|&i| u64::from(i) < vertex_count)
                .ok_or_else(|| {
                    ParseError::at(
                        at,
                        Problem::IndexOutOfRange {
                            index,
                            vertex_count,
                        },
                    )
                })
        };
        let first = read_index()?;
        let mut previous = read_index()?;
        for _ in 2..n {
            let next = read_index()?;
            if soup.triangles.len() as u64 >= max_triangles {
                return Err(ParseError::at(
                    at,
                    Problem::LimitsExceeded {
                        what: "triangles",
                        requested: soup.triangles.len() as u64 + 1,
                        max: max_triangles,
                    },
                ));
            }
            soup.triangles.push([first, previous, next]);
            previous = next;
        }
        if n > 3 {
            soup.triangulated_polygons += 1;
        }
    }
    Ok(())
}

/// A count already checked against the bytes present, as a `usize`.
fn to_usize(count: u64) -> usize {
    usize::try_from(count).unwrap_or(usize::MAX)
}

/// The lines of a text file that hold something other than whitespace and comments.
struct Lines<'a> {
    bytes: &'a [u8],
    /// Start of the unread part.
    pos: usize,
    /// 1-based number of the line last returned (0 before the first).
    line: u64,
}

impl<'a> Lines<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Lines {
            bytes: bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes),
            pos: 0,
            line: 0,
        }
    }

    /// Bytes not yet read.
    fn bytes_left(&self) -> u64 {
        self.bytes.len().saturating_sub(self.pos) as u64
    }

    /// The words of the next line that has any, comments removed.
    fn next_record(&mut self) -> Option<Words<'a>> {
        loop {
            let rest = self.bytes.get(self.pos..)?;
            if rest.is_empty() {
                return None;
            }
            let end = rest.iter().position(|&b| b == b'\n');
            let line = &rest[..end.unwrap_or(rest.len())];
            self.pos += end.map_or(rest.len(), |e| e + 1);
            self.line += 1;
            let line = match line.iter().position(|&b| b == b'#') {
                Some(hash) => &line[..hash],
                None => line,
            };
            let words = Words { line };
            if words.has_more() {
                return Some(words);
            }
        }
    }
}

/// The whitespace-separated words of one line.
#[derive(Clone)]
struct Words<'a> {
    line: &'a [u8],
}

impl<'a> Words<'a> {
    fn has_more(&self) -> bool {
        self.line.iter().any(|b| !b.is_ascii_whitespace())
    }
}

impl<'a> Iterator for Words<'a> {
    type Item = &'a [u8];

    fn next(&mut self) -> Option<&'a [u8]> {
        let start = self.line.iter().position(|b| !b.is_ascii_whitespace())?;
        let rest = &self.line[start..];
        let end = rest
            .iter()
            .position(|b| b.is_ascii_whitespace())
            .unwrap_or(rest.len());
        let (word, rest) = rest.split_at(end);
        self.line = rest;
        Some(word)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Soup, ParseError> {
        parse(text.as_bytes(), &ImportLimits::default())
    }

    fn problem_at(text: &str) -> (Option<Location>, Problem) {
        let e = read(text).expect_err("the file is malformed");
        (e.at, e.problem)
    }

    const SQUARE: &str = "OFF\n4 1 4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";

    #[test]
    fn reads_a_quad_as_two_triangles() {
        let soup = read(SQUARE).unwrap();
        assert_eq!(soup.positions.len(), 4);
        assert_eq!(soup.positions[2], DVec3::new(1.0, 1.0, 0.0));
        assert_eq!(soup.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(soup.triangulated_polygons, 1);
    }

    #[test]
    fn reads_counts_on_the_header_line_comments_crlf_and_colours() {
        let text = "# made by hand\r\nCOFF 3 1 0 # counts here\r\n\r\n\
                    0 0 0 255 0 0 255\r\n# a comment between vertices\r\n\
                    1 0 0 0 255 0 255\r\n0 1 0 0 0 255 255\r\n3 0 1 2 0.5 0.5 0.5 1\r\n";
        let soup = read(text).unwrap();
        assert_eq!(soup.positions[1], DVec3::X);
        assert_eq!(soup.triangles, vec![[0, 1, 2]]);
        assert_eq!(soup.triangulated_polygons, 0);
    }

    #[test]
    fn reads_variants_with_extra_vertex_values() {
        for keyword in ["NOFF", "CNOFF", "STOFF", "STCNOFF"] {
            let text = format!("{keyword}\n3 1 0\n0 0 0 9 9 9 9 9 9 9\n1 0 0 9 9 9 9 9 9 9\n0 1 0 9 9 9 9 9 9 9\n3 2 1 0\n");
            let soup = read(&text).unwrap();
            assert_eq!(soup.positions[2], DVec3::Y, "{keyword}");
            assert_eq!(soup.triangles, vec![[2, 1, 0]], "{keyword}");
        }
    }

    #[test]
    fn reports_empty_files() {
        assert_eq!(problem_at(""), (None, Problem::Empty));
        assert_eq!(
            problem_at("  \n# only a comment\n\n"),
            (None, Problem::Empty)
        );
    }

    #[test]
    fn reports_other_formats_and_unsupported_variants() {
        let not_off = Problem::NotThisFormat { expected: "OFF" };
        assert_eq!(
            problem_at("ply\nformat ascii 1.0\n"),
            (Some(Location::Line(1)), not_off.clone())
        );
        assert_eq!(
            problem_at("\n\nXOFF 3 1 0\n"),
            (Some(Location::Line(3)), not_off)
        );
        assert!(matches!(
            problem_at("4OFF\n1 0 0\n0 0 0 1\n").1,
            Problem::Unsupported { .. }
        ));
        assert!(matches!(
            problem_at("OFF BINARY\n").1,
            Problem::Unsupported { .. }
        ));
    }

    #[test]
    fn reports_syntax_errors_with_their_line() {
        assert_eq!(
            problem_at("OFF\nthree 1 0\n"),
            (
                Some(Location::Line(2)),
                Problem::Syntax {
                    expected: "the vertex count",
                    found: "three".into()
                }
            )
        );
        assert_eq!(
            problem_at("OFF\n3 1 0\n0 0 0\n1 0 zero\n0 1 0\n3 0 1 2\n").0,
            Some(Location::Line(4))
        );
        assert_eq!(
            problem_at("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n"),
            (
                Some(Location::Line(6)),
                Problem::Syntax {
                    expected: "a vertex index",
                    found: String::new()
                }
            )
        );
    }

    #[test]
    fn reports_truncation_as_a_count_mismatch() {
        assert_eq!(
            problem_at("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n\n\n\n\n\n"),
            (
                // The end of the file.
                Some(Location::Line(10)),
                Problem::CountMismatch {
                    what: "faces",
                    declared: 1,
                    found: 0
                }
            )
        );
        assert_eq!(
            problem_at("OFF\n3 0 0\n0 0 0\n1 0 0\n\n\n\n\n\n\n"),
            (
                Some(Location::Line(10)),
                Problem::CountMismatch {
                    what: "vertices",
                    declared: 3,
                    found: 2
                }
            )
        );
    }

    #[test]
    fn reports_non_finite_coordinates() {
        assert_eq!(
            problem_at("OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n"),
            (
                Some(Location::Line(4)),
                Problem::NonFiniteCoordinate { vertex: 1 }
            )
        );
        assert_eq!(
            problem_at("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1e999 0\n3 0 1 2\n"),
            (
                Some(Location::Line(5)),
                Problem::NonFiniteCoordinate { vertex: 2 }
            )
        );
    }

    #[test]
    fn reports_indices_out_of_range() {
        assert_eq!(
            problem_at("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
            (
                Some(Location::Line(6)),
                Problem::IndexOutOfRange {
                    index: 3,
                    vertex_count: 3
                }
            )
        );
        assert_eq!(
            problem_at("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 -1 1 2\n"),
            (
                Some(Location::Line(6)),
                Problem::IndexOutOfRange {
                    index: -1,
                    vertex_count: 3
                }
            )
        );
    }

    #[test]
    fn reports_faces_with_fewer_than_three_vertices() {
        assert_eq!(
            problem_at("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n"),
            (
                Some(Location::Line(6)),
                Problem::FaceTooSmall { vertices: 2 }
            )
        );
    }

    #[test]
    fn checks_counts_against_limits_and_bytes_before_allocating() {
        assert_eq!(
            problem_at("OFF\n4000000000 1 0\n0 0 0\n"),
            (
                Some(Location::Line(2)),
                Problem::LimitsExceeded {
                    what: "vertices",
                    requested: 4_000_000_000,
                    max: 1 << 27
                }
            )
        );
        assert!(matches!(
            problem_at("OFF\n100000 100000 0\n0 0 0\n"),
            (Some(Location::Line(2)), Problem::Truncated { .. })
        ));
        let tight = ImportLimits {
            max_faces: 1,
            ..ImportLimits::default()
        };
        let e = parse(SQUARE.as_bytes(), &tight).unwrap_err();
        assert_eq!(
            e.problem,
            Problem::LimitsExceeded {
                what: "triangles",
                requested: 2,
                max: 1
            }
        );
    }
}
