//! OBJ reader: vertex positions and polygonal faces of a Wavefront OBJ file.
//!
//! Only `v` and `f` statements matter to ellip; texture coordinates, normals, groups,
//! smoothing groups and materials are ignored (and `mtllib` never opens a file). Polygons are
//! fanned into triangles from their first vertex. `l` polylines and `p` points are skipped
//! with a warning.
//!
//! The file is read in two steps:
//!
//! 1. [`scan`], our own single pass over the lines, checks every `v` and `f` statement with
//!    its line number (numbers parse, coordinates are finite, every face has at least three
//!    vertices, every index refers to an existing vertex), counts vertices and triangles
//!    against [`ImportLimits`], and writes a normalised copy holding only `v x y z [w]` and
//!    `f` lines.
//! 2. tobj parses that copy into faces.
//!
//! tobj is never given the file itself because, fed hostile or merely unusual input, tobj 4
//! panics (arithmetic overflow in debug builds) on out-of-range negative texture or normal
//! indices, turns `l` polylines of three or more points into faces, rejects files where only
//! some vertices carry colours, fails on an empty `usemtl`, and reports errors without line
//! numbers. The normalised copy contains nothing that can provoke any of that.

use super::{check_limit, excerpt, ImportLimits, Location, ParseError, Problem, Soup};
use glam::DVec3;
use std::str::FromStr;

/// What [`scan`] learned about a file.
#[derive(Debug, Default)]
struct Scan {
    /// The `v` and `f` statements, normalised, one per line.
    normalized: Vec<u8>,
    /// `v` statements.
    vertices: u64,
    /// `f` statements.
    faces: u64,
    /// Triangles after fanning.
    triangles: u64,
    /// Faces with more than three vertices.
    polygons: u64,
    /// Skipped `l` statements.
    polylines: u64,
    /// Skipped `p` statements.
    points: u64,
    /// Other statements (not comments, not blank).
    others: u64,
}

/// Parses an OBJ file into a soup of positions and triangles.
pub(crate) fn parse(bytes: &[u8], limits: &ImportLimits) -> Result<Soup, ParseError> {
    let scan = scan(bytes, limits)?;
    if scan.faces == 0 {
        return Err(ParseError::whole(describe_faceless(&scan)));
    }
    let models = load_with_tobj(&scan.normalized)?;
    let mut soup = Soup::default();
    for model in &models {
        append_model(&model.mesh, &mut soup)?;
    }
    soup.triangulated_polygons = scan.polygons;
    if scan.polylines > 0 {
        soup.warnings.push(format!(
            "skipped {} polyline (l) statements",
            scan.polylines
        ));
    }
    if scan.points > 0 {
        soup.warnings
            .push(format!("skipped {} point (p) statements", scan.points));
    }
    Ok(soup)
}

/// The error for a file without faces: empty, not OBJ at all, or a point cloud.
fn describe_faceless(scan: &Scan) -> Problem {
    if scan.vertices == 0 && scan.polylines == 0 && scan.points == 0 {
        if scan.others == 0 {
            Problem::Empty
        } else {
            Problem::NotThisFormat { expected: "OBJ" }
        }
    } else {
        Problem::Unsupported {
            what: format!(
                "an OBJ file without faces ({} vertices, {} polylines, {} points)",
                scan.vertices, scan.polylines, scan.points
            ),
        }
    }
}

/// Checks every line and writes the normalised copy that tobj parses.
fn scan(bytes: &[u8], limits: &ImportLimits) -> Result<Scan, ParseError> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut scan = Scan {
        normalized: Vec::with_capacity(bytes.len()),
        ..Scan::default()
    };
    // Faces naming a vertex not yet defined: legal only if the vertex comes later.
    let mut forward_references: Vec<(u64, i64)> = Vec::new();
    for (line_index, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = u64::try_from(line_index).map_or(u64::MAX, |n| n.saturating_add(1));
        let at = Location::Line(line);
        let mut words = raw
            .split(|b| b.is_ascii_whitespace())
            .filter(|w| !w.is_empty());
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            b"v" => {
                let vertex = scan.vertices;
                scan_vertex(words, vertex, &mut scan.normalized)
                    .map_err(|p| ParseError::at(at, p))?;
                scan.vertices += 1;
                check_limit(
                    "vertices",
                    scan.vertices,
                    limits.max_vertices.min(u32::MAX.into()),
                )
                .map_err(ParseError::whole)?;
            }
            b"f" => {
                let corners = scan_face(
                    words,
                    scan.vertices,
                    line,
                    &mut forward_references,
                    &mut scan.normalized,
                )
                .map_err(|p| ParseError::at(at, p))?;
                scan.faces += 1;
                scan.triangles += corners - 2;
                if corners > 3 {
                    scan.polygons += 1;
                }
                check_limit("triangles", scan.triangles, limits.max_faces)
                    .map_err(ParseError::whole)?;
            }
            b"l" => scan.polylines += 1,
            b"p" => scan.points += 1,
            _ if keyword.starts_with(b"#") => {}
            _ => scan.others += 1,
        }
    }
    if let Some(&(line, index)) = forward_references
        .iter()
        .find(|&&(_, index)| index.unsigned_abs() > scan.vertices)
    {
        return Err(ParseError::at(
            Location::Line(line),
            Problem::IndexOutOfRange {
                index,
                vertex_count: scan.vertices,
            },
        ));
    }
    Ok(scan)
}

/// Checks the words of a `v` statement after the keyword and writes `v x y z [w]`.
/// tobj reads `x y z`, then optionally `w` (dividing the coordinates by it) or three colour
/// components; colours are dropped here.
fn scan_vertex<'a>(
    mut words: impl Iterator<Item = &'a [u8]>,
    vertex: u64,
    out: &mut Vec<u8>,
) -> Result<(), Problem> {
    let mut xyz: [&[u8]; 3] = [b""; 3];
    let mut coords = [0.0f64; 3];
    for (word, coord) in xyz.iter_mut().zip(coords.iter_mut()) {
        let Some(w) = words.next() else {
            return Err(Problem::Syntax {
                expected: "three coordinates",
                found: String::new(),
            });
        };
        *word = w;
        *coord = parse_number(w)?;
    }
    let rest: Vec<&[u8]> = words.take(4).collect();
    let w = match rest.as_slice() {
        [] | [_, _, _] => None,
        [w] => Some(*w),
        [extra, ..] => {
            return Err(Problem::Syntax {
                expected: "x y z, x y z w or x y z r g b",
                found: excerpt(extra),
            })
        }
    };
    out.extend_from_slice(b"v");
    for word in xyz {
        out.push(b' ');
        out.extend_from_slice(word);
    }
    if let Some(w_word) = w {
        let w = parse_number(w_word)?;
        if w == 0.0 {
            return Err(Problem::Syntax {
                expected: "a non-zero w",
                found: excerpt(w_word),
            });
        }
        // tobj divides by w in the same precision, so this is exactly what it will produce.
        for c in &mut coords {
            *c /= w;
        }
        out.push(b' ');
        out.extend_from_slice(w_word);
    }
    out.push(b'\n');
    if coords.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(Problem::NonFiniteCoordinate { vertex })
    }
}

/// Checks the words of an `f` statement after the keyword, copies them to `out`, and returns
/// the number of corners. `vertices` is the number of vertices defined so far; references
/// beyond it are recorded in `forward` to be checked at the end of the file.
fn scan_face<'a>(
    words: impl Iterator<Item = &'a [u8]>,
    vertices: u64,
    line: u64,
    forward: &mut Vec<(u64, i64)>,
    out: &mut Vec<u8>,
) -> Result<u64, Problem> {
    let mut corners = 0u64;
    out.extend_from_slice(b"f");
    for word in words {
        let index = parse_corner(word)?;
        if index == 0 || (index < 0 && index.unsigned_abs() > vertices) {
            return Err(Problem::IndexOutOfRange {
                index,
                vertex_count: vertices,
            });
        }
        if index > 0 && index.unsigned_abs() > vertices {
            forward.push((line, index));
        }
        corners += 1;
        out.push(b' ');
        out.extend_from_slice(word);
    }
    out.push(b'\n');
    if corners < 3 {
        return Err(Problem::FaceTooSmall { vertices: corners });
    }
    Ok(corners)
}

/// Reads one face corner (`v`, `v/vt`, `v//vn` or `v/vt/vn`) and returns its vertex index
/// as written. The texture and normal indices must be integers (tobj parses them) but are
/// otherwise ignored.
fn parse_corner(word: &[u8]) -> Result<i64, Problem> {
    let malformed = || Problem::Syntax {
        expected: "a face corner v, v/vt, v//vn or v/vt/vn",
        found: excerpt(word),
    };
    let mut parts = word.split(|&b| b == b'/');
    let vertex = parts.next().ok_or_else(malformed)?;
    let vertex = std::str::from_utf8(vertex)
        .ok()
        .and_then(|s| i64::from_str(s).ok())
        .ok_or_else(malformed)?;
    let mut others = 0;
    for part in parts {
        others += 1;
        let valid = part.is_empty()
            || std::str::from_utf8(part)
                .ok()
                .is_some_and(|s| isize::from_str(s).is_ok());
        if others > 2 || !valid {
            return Err(malformed());
        }
    }
    Ok(vertex)
}

/// Parses a coordinate exactly as tobj does (`f64::from_str`).
fn parse_number(word: &[u8]) -> Result<f64, Problem> {
    std::str::from_utf8(word)
        .ok()
        .and_then(|s| f64::from_str(s).ok())
        .ok_or_else(|| Problem::Syntax {
            expected: "a number",
            found: excerpt(word),
        })
}

/// Runs tobj over the normalised copy: positions and faces only, polygons kept whole.
fn load_with_tobj(normalized: &[u8]) -> Result<Vec<tobj::Model>, ParseError> {
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = normalized;
    // The copy holds no `mtllib`, so this loader is never called; it would load nothing.
    let ignore_materials =
        |_: &std::path::Path| -> tobj::MTLLoadResult { Ok((Vec::new(), Default::default())) };
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, ignore_materials)
        .map_err(|e| {
            // Everything tobj checks was checked by `scan`, with line numbers.
            ParseError::whole(Problem::Syntax {
                expected: "an OBJ file tobj accepts",
                found: e.to_string(),
            })
        })?;
    Ok(models)
}

/// Appends one tobj model to the soup, fanning its polygons.
fn append_model(mesh: &tobj::Mesh, soup: &mut Soup) -> Result<(), ParseError> {
    let inconsistent = |what: &str| {
        ParseError::whole(Problem::Syntax {
            expected: "consistent faces from tobj",
            found: what.to_owned(),
        })
    };
    let base = soup.positions.len();
    soup.positions.extend(
        mesh.positions
            .chunks_exact(3)
            .map(|p| DVec3::new(p[0], p[1], p[2])),
    );
    let count = soup.positions.len();
    let vertex = |i: u32| -> Result<u32, ParseError> {
        usize::try_from(i)
            .ok()
            .and_then(|i| i.checked_add(base))
            .filter(|&i| i < count)
            .and_then(|i| u32::try_from(i).ok())
            .ok_or_else(|| inconsistent("a vertex index out of range"))
    };
    let mut fan = |corners: &[u32]| -> Result<(), ParseError> {
        let Some((&first, rest)) = corners.split_first() else {
            return Err(inconsistent("an empty face"));
        };
        let first = vertex(first)?;
        for pair in rest.windows(2) {
            soup.triangles
                .push([first, vertex(pair[0])?, vertex(pair[1])?]);
        }
        Ok(())
    };
    if mesh.face_arities.is_empty() {
        // tobj leaves the arities empty when every face is a triangle.
        let triangles = mesh.indices.chunks_exact(3);
        if !triangles.remainder().is_empty() {
            return Err(inconsistent("a partial triangle"));
        }
        for triangle in triangles {
            fan(triangle)?;
        }
    } else {
        let mut start = 0usize;
        for &arity in &mesh.face_arities {
            let end = usize::try_from(arity)
                .ok()
                .and_then(|n| start.checked_add(n))
                .ok_or_else(|| inconsistent("a face arity"))?;
            let corners = mesh
                .indices
                .get(start..end)
                .ok_or_else(|| inconsistent("a face past the indices"))?;
            if corners.len() < 3 {
                return Err(inconsistent("a face of fewer than three vertices"));
            }
            fan(corners)?;
            start = end;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Soup, ParseError> {
        parse(text.as_bytes(), &ImportLimits::default())
    }

    fn error(text: &[u8]) -> (Option<Location>, Problem) {
        let e = parse(text, &ImportLimits::default()).expect_err("should be rejected");
        (e.at, e.problem)
    }

    const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

    #[test]
    fn reads_a_triangle() {
        let soup = read(&format!("{TRIANGLE}f 1 2 3\n")).unwrap();
        assert_eq!(soup.positions.len(), 3);
        assert_eq!(soup.triangles, vec![[0, 1, 2]]);
        assert_eq!(soup.positions[1], DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(soup.triangulated_polygons, 0);
        assert!(soup.warnings.is_empty());
    }

    #[test]
    fn fans_polygons_and_counts_them() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 1 0\nf 1 2 3 4 5\nf 1 2 3\n";
        let soup = read(text).unwrap();
        assert_eq!(soup.triangles.len(), 4);
        assert_eq!(soup.triangulated_polygons, 1);
        // Fanned from the first corner: every triangle of the pentagon contains it.
        let first = soup.triangles[0][0];
        assert!(soup.triangles[..3].iter().all(|t| t[0] == first));
    }

    #[test]
    fn keeps_double_precision() {
        let text = "v 0.1000000000000001 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let soup = read(text).unwrap();
        let x = soup.positions.iter().map(|p| p.x).fold(f64::NAN, f64::min);
        assert_eq!(x, 0.0);
        assert!(soup.positions.iter().any(|p| p.x == 0.1000000000000001));
    }

    #[test]
    fn resolves_relative_indices_and_ignores_uv_and_normals() {
        let text = format!("{TRIANGLE}vt 0 0\nvn 0 0 1\nf -3/1/1 -2/-1/-1 -1//1\n");
        let soup = read(&text).unwrap();
        assert_eq!(soup.triangles.len(), 1);
        let [a, b, c] = soup.triangles[0];
        let corners: Vec<DVec3> = [a, b, c]
            .iter()
            .map(|&i| soup.positions[i as usize])
            .collect();
        assert_eq!(corners[0], DVec3::ZERO);
        assert_eq!(corners[1], DVec3::X);
        assert_eq!(corners[2], DVec3::Y);
    }

    #[test]
    fn divides_by_w_and_drops_colours() {
        let text = "v 2 0 0 2\nv 1 0 0 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let soup = read(text).unwrap();
        // `2 0 0 2` is (1, 0, 0); the colours of the second vertex are not coordinates.
        assert_eq!(soup.positions, vec![DVec3::X, DVec3::X, DVec3::Y]);
    }

    #[test]
    fn accepts_forward_references_crlf_bom_and_unknown_statements() {
        let text = "\u{feff}# made by hand\r\nmtllib /etc/passwd\r\nusemtl\r\no a\r\ng\r\ns 1\r\nf 1 2 3\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\n";
        let soup = read(text).unwrap();
        assert_eq!(soup.triangles.len(), 1);
    }

    #[test]
    fn tolerates_non_utf8_outside_v_and_f() {
        let mut text = b"# caf\xe9 cr\xe9\xe9\ng gr\xfcn\n".to_vec();
        text.extend_from_slice(format!("{TRIANGLE}f 1 2 3\n").as_bytes());
        assert_eq!(
            parse(&text, &ImportLimits::default())
                .unwrap()
                .triangles
                .len(),
            1
        );
    }

    #[test]
    fn hands_tobj_only_vertices_and_faces() {
        let text = format!(
            "mtllib a.mtl\nusemtl x\no a\ng b\ns 1\nvt 0 0\nvn 0 0 1\n{TRIANGLE}v 1 1 1 0.5 0.5 0.5\nl 1 2\np 1\nf 1/1/1 2//1 3/1\n"
        );
        let scan = scan(text.as_bytes(), &ImportLimits::default()).unwrap();
        let normalized = String::from_utf8(scan.normalized).unwrap();
        assert_eq!(
            normalized,
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nf 1/1/1 2//1 3/1\n"
        );
    }

    #[test]
    fn skips_polylines_and_points_with_warnings() {
        let text = format!("{TRIANGLE}l 1 2 3\np 1\nf 1 2 3\n");
        let soup = read(&text).unwrap();
        assert_eq!(soup.triangles.len(), 1);
        assert_eq!(soup.warnings.len(), 2);
        assert!(soup.warnings[0].contains("polyline"));
    }

    #[test]
    fn rejects_bad_indices_at_their_line() {
        let cases: [(&str, i64); 4] = [
            ("f 0 1 2", 0),
            ("f 1 2 4", 4),
            ("f -4 -2 -1", -4),
            ("f 1 2 9223372036854775807", i64::MAX),
        ];
        for (face, index) in cases {
            let text = format!("{TRIANGLE}{face}\n");
            assert_eq!(
                error(text.as_bytes()),
                (
                    Some(Location::Line(4)),
                    Problem::IndexOutOfRange {
                        index,
                        vertex_count: 3
                    }
                ),
                "{face}"
            );
        }
        // i64::MIN: its magnitude does not fit an i64.
        let text = format!("{TRIANGLE}f -9223372036854775808 1 2\n");
        assert!(matches!(
            error(text.as_bytes()),
            (Some(Location::Line(4)), Problem::IndexOutOfRange { .. })
        ));
    }

    #[test]
    fn rejects_out_of_range_uv_indices_that_make_tobj_overflow() {
        // tobj 4 multiplies these without overflow checks; they never reach it.
        let text = format!("{TRIANGLE}vt 0 0\nf 1/-5 2/-5 3/-5\n");
        assert_eq!(read(&text).unwrap().triangles.len(), 1);
        let text = format!("{TRIANGLE}vt 0 0\nf 1/-9223372036854775808 2/1 3/1\n");
        assert_eq!(read(&text).unwrap().triangles.len(), 1);
        let text = format!("{TRIANGLE}vn 0 0 1\nf 1//x 2//1 3//1\n");
        assert!(matches!(
            error(text.as_bytes()),
            (Some(Location::Line(5)), Problem::Syntax { .. })
        ));
        let text = format!("{TRIANGLE}f 1/1/1/1 2 3\n");
        assert!(matches!(
            error(text.as_bytes()),
            (Some(Location::Line(4)), Problem::Syntax { .. })
        ));
    }

    #[test]
    fn rejects_small_faces() {
        for (face, n) in [("f 1 2", 2), ("f 1", 1), ("f", 0)] {
            let text = format!("{TRIANGLE}\n{face}\n");
            assert_eq!(
                error(text.as_bytes()),
                (
                    Some(Location::Line(5)),
                    Problem::FaceTooSmall { vertices: n }
                )
            );
        }
    }

    #[test]
    fn rejects_non_finite_and_malformed_coordinates() {
        for (v, line) in [
            ("v nan 0 0", 2),
            ("v 1e999 0 0", 2),
            ("v 0 inf 0", 2),
            ("v 1 1 1 1e-320", 2),
        ] {
            let text = format!("v 0 0 0\n{v}\nv 0 1 0\nf 1 2 3\n");
            assert_eq!(
                error(text.as_bytes()),
                (
                    Some(Location::Line(line)),
                    Problem::NonFiniteCoordinate { vertex: 1 }
                ),
                "{v}"
            );
        }
        for v in [
            "v 1 2",
            "v 1 x 3",
            "v 1 2 3 4 5",
            "v 1 2 3 0",
            "v 1 2 \u{a0}3",
        ] {
            let text = format!("v 0 0 0\n{v}\nv 0 1 0\nf 1 2 3\n");
            assert!(
                matches!(
                    error(text.as_bytes()),
                    (Some(Location::Line(2)), Problem::Syntax { .. })
                ),
                "{v}"
            );
        }
        let text = b"v 0 0 0\nv 1 0 0\nv 0 1 \xff\xfe\nf 1 2 3\n";
        assert!(matches!(
            error(text),
            (Some(Location::Line(3)), Problem::Syntax { .. })
        ));
    }

    #[test]
    fn tells_empty_from_faceless_from_foreign() {
        assert_eq!(error(b"").1, Problem::Empty);
        assert_eq!(error(b"# only\n\n   # comments\n").1, Problem::Empty);
        assert_eq!(
            error(b"hello world\n").1,
            Problem::NotThisFormat { expected: "OBJ" }
        );
        assert!(matches!(
            error(TRIANGLE.as_bytes()).1,
            Problem::Unsupported { .. }
        ));
        assert!(matches!(
            error(b"\x00\x01\x02\xff\x80garbage\n\x13\x37").1,
            Problem::NotThisFormat { .. }
        ));
    }

    #[test]
    fn checks_limits_while_counting() {
        let limits = ImportLimits {
            max_vertices: 2,
            ..ImportLimits::default()
        };
        let text = format!("{TRIANGLE}f 1 2 3\n");
        let e = parse(text.as_bytes(), &limits).unwrap_err();
        assert!(matches!(
            e.problem,
            Problem::LimitsExceeded {
                what: "vertices",
                requested: 3,
                max: 2
            }
        ));
        let limits = ImportLimits {
            max_faces: 2,
            ..ImportLimits::default()
        };
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 1 2 3\n";
        let e = parse(text.as_bytes(), &limits).unwrap_err();
        assert!(matches!(
            e.problem,
            Problem::LimitsExceeded {
                what: "triangles",
                requested: 3,
                max: 2
            }
        ));
    }

    #[test]
    fn never_panics_on_mangled_input() {
        let base = format!(
            "{TRIANGLE}vt 0 0\nvn 0 0 1\nf 1/1/1 2/-1/-1 -1//1\nl 1 2\nv 1 1 1\nf 4 3 2 1\n"
        );
        let base = base.as_bytes();
        let mut rng = crate::rng::SplitMix64::new(7);
        let alphabet = b" \n/-+0123456789.efvnlt#\xff";
        let iterations: u64 = std::env::var("ELLIP_FUZZ_ITERATIONS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(2000);
        let mut ok = 0u64;
        for _ in 0..iterations {
            let mut text = base.to_vec();
            for _ in 0..1 + rng.below(4) {
                let i = rng.below(text.len() as u64) as usize;
                text[i] = alphabet[rng.below(alphabet.len() as u64) as usize];
            }
            match parse(&text, &ImportLimits::default()) {
                Ok(soup) => {
                    ok += 1;
                    let n = soup.positions.len() as u32;
                    assert!(soup.triangles.iter().flatten().all(|&i| i < n));
                    assert!(soup.positions.iter().all(|p| p.is_finite()));
                }
                // The scan must catch everything tobj would reject, with a line number.
                Err(e) => assert!(
                    e.at.is_some()
                        || e.problem == Problem::Empty
                        || matches!(
                            e.problem,
                            Problem::NotThisFormat { .. } | Problem::Unsupported { .. }
                        ),
                    "{:?}: {e:?}",
                    String::from_utf8_lossy(&text)
                ),
            }
        }
        // Some mangled files stay readable, and not all.
        eprintln!("mangled OBJ: {ok} of {iterations} read");
        assert!(ok > 0 && ok < iterations, "{ok} of {iterations} read");
    }
}
