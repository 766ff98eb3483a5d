//! The `.ellip` codec: round trips, golden files, invalid files, hostile bytes, limits,
//! property tests, fuzz regressions.
//!
//! Regenerate the committed fixtures (a deliberate format change) with
//! `ELLIP_REGENERATE_FIXTURES=1 cargo test --test format`.

use ellip::compare::distance_to_segment;
use ellip::ellipsoid::Ellipsoid;
use ellip::format::consts::*;
use ellip::format::container::{inflate, read_container, write_container, RawSection};
use ellip::format::sample::{self, Piece, RawEllipsoid, Recipe};
use ellip::format::{self, DecodeError, EncodeOptions, Limits, Tag};
use ellip::representation::{Metadata, Representation};
use glam::DVec3;
use proptest::prelude::*;
use std::path::{Path, PathBuf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ellip")
}

fn regenerate() -> bool {
    std::env::var_os("ELLIP_REGENERATE_FIXTURES").is_some()
}

fn encode(rep: &Representation) -> Vec<u8> {
    format::encode(rep, &EncodeOptions::default()).expect("encodes")
}

/// Asserts `decoded` equals `original` up to the stated bounds: points and ellipsoid
/// surfaces within the grid's error bound (spec §6.2, §6.4; plus the rounding of binary64
/// arithmetic), topology and metadata exact.
fn assert_close(original: &Representation, decoded: &Representation, bound: f64) {
    assert_eq!(decoded.ellipsoids.len(), original.ellipsoids.len());
    for (a, b) in original.ellipsoids.iter().zip(&decoded.ellipsoids) {
        assert_eq!(a.sign, b.sign);
        let magnitude = a.center.length() + a.radii.max_element();
        let tolerance = bound * (1.0 + 1e-9) + 16.0 * f64::EPSILON * magnitude;
        for u in [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::ONE.normalize(),
            DVec3::new(0.3, -0.8, 0.52).normalize(),
        ] {
            let d = (a.from_unit_sphere(u) - b.from_unit_sphere(u)).length();
            assert!(d <= tolerance, "ellipsoid surface moved {d} > {tolerance}");
        }
    }
    assert_eq!(decoded.arcs.len(), original.arcs.len());
    for (i, (a, b)) in original.arcs.iter().zip(&decoded.arcs).enumerate() {
        assert_eq!((a.closed, a.left, a.right), (b.closed, b.left, b.right));
        let pa = original.arc_positions(i).unwrap();
        let pb = decoded.arc_positions(i).unwrap();
        assert_eq!(pa.len(), pb.len());
        for (p, q) in pa.iter().zip(&pb) {
            assert!(
                (*p - *q).length() <= bound * (1.0 + 1e-9) + 1e-12,
                "{p} vs {q}, bound {bound}"
            );
        }
    }
    assert_eq!(decoded.cycles, original.cycles);
    assert_eq!(decoded.metadata, original.metadata);
}

/// Encode → decode → encode: identical bytes, decoded values within the stated bounds.
fn check_round_trip(rep: &Representation, options: &EncodeOptions) {
    let bytes = format::encode(rep, options).expect("encodes");
    let decoded = format::decode(&bytes, &Limits::default()).expect("decodes");
    let summary = format::inspect(&bytes, &Limits::default()).unwrap();
    assert_close(rep, &decoded, summary.error_bound);
    let again = format::encode(&decoded, options).expect("re-encodes");
    assert!(again == bytes, "re-encoding is not byte-identical");
    assert_eq!(format::decode(&again, &Limits::default()).unwrap(), decoded);
}

#[test]
fn samples_round_trip_at_every_bit_depth() {
    let mut reps: Vec<Representation> = sample::golden().into_iter().map(|(_, r)| r).collect();
    reps.push(sample::lunes(6, 50, 0.01));
    for rep in &reps {
        for bits in [1, 4, 12, 14, 16, 24] {
            check_round_trip(rep, &EncodeOptions { bits });
        }
    }
}

#[test]
fn encoding_is_deterministic_and_rejects_bad_input() {
    let rep = sample::lunes(4, 10, 0.02);
    assert_eq!(encode(&rep), encode(&rep.clone()));
    for bits in [0, 25] {
        assert!(matches!(
            format::encode(&rep, &EncodeOptions { bits }),
            Err(format::EncodeError::Options { .. })
        ));
    }
    let mut bad = rep.clone();
    bad.ellipsoids[1].radii.y = -1.0;
    assert!(matches!(
        format::encode(&bad, &EncodeOptions::default()),
        Err(format::EncodeError::Invalid(_))
    ));
}

#[test]
fn unused_points_are_dropped_and_the_pool_renumbered_by_first_use() {
    let mut rep = sample::two_hemispheres();
    rep.points.insert(0, DVec3::splat(100.0)); // unused, and would stretch the grid
    for a in &mut rep.arcs {
        for i in &mut a.points {
            *i += 1;
        }
        a.points.reverse();
    }
    for cs in &mut rep.cycles {
        for c in cs {
            for r in &mut c.arcs {
                r.reversed = !r.reversed;
            }
        }
    }
    // Reversing the loop and flipping the cycles keeps the same geometry and topology
    // (left/right stay: swap them to keep the region on the left).
    rep.arcs[0].left = 1;
    rep.arcs[0].right = ellip::representation::Side::Region(0);
    let decoded = format::decode(&encode(&rep), &Limits::default()).unwrap();
    assert_eq!(decoded.points.len(), 12);
    assert_eq!(decoded.arcs[0].points, (0..12).collect::<Vec<u32>>());
    let summary = format::inspect(&encode(&rep), &Limits::default()).unwrap();
    assert!(
        summary.grid.max.max_element() < 3.0,
        "unused point stretched the grid"
    );
}

#[test]
fn simplified_arcs_stay_within_tolerance_and_keep_junctions() {
    let original = sample::lunes(5, 200, 0.002);
    let mut rep = original.clone();
    let tolerance = 0.01;
    let removed = rep.simplify_arcs(tolerance);
    assert!(rep.validate().is_ok());
    assert_eq!(removed, original.points.len() - rep.points.len());
    assert!(removed > 900, "only {removed} removed");
    for (i, a) in rep.arcs.iter().enumerate() {
        let before = original.arc_positions(i).unwrap();
        let after = rep.arc_positions(i).unwrap();
        assert_eq!(after.first(), before.first());
        assert_eq!(after.last(), before.last());
        assert!(a.points.len() >= 2);
        for p in &before {
            let d = after
                .windows(2)
                .map(|w| distance_to_segment(*p, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(d <= tolerance + 1e-12, "{d}");
        }
    }
    assert_eq!(rep.metadata.simplify_tolerance, Some(tolerance));
    // Closed loops keep at least three points.
    let mut loops = sample::two_hemispheres();
    loops.simplify_arcs(10.0);
    assert_eq!(loops.arcs[0].points.len(), 3);
    assert!(loops.validate().is_ok());
}

// ---------------------------------------------------------------------------------------
// Golden files

#[test]
fn golden_files_decode_to_their_committed_digests() {
    let dir = fixtures().join("v1");
    if regenerate() {
        std::fs::create_dir_all(&dir).unwrap();
        for (name, rep) in sample::golden() {
            std::fs::write(dir.join(format!("{name}.ellip")), encode(&rep)).unwrap();
        }
    }
    let mut seen = 0;
    for (name, rep) in sample::golden() {
        let bytes = std::fs::read(dir.join(format!("{name}.ellip"))).unwrap();
        let decoded = format::decode(&bytes, &Limits::default()).unwrap();
        let digest = serde_json::to_string_pretty(&decoded).unwrap() + "\n";
        let digest_path = dir.join(format!("{name}.json"));
        if regenerate() {
            std::fs::write(&digest_path, &digest).unwrap();
        }
        let committed = std::fs::read_to_string(&digest_path).unwrap();
        assert!(
            digest == committed,
            "{name}.ellip no longer decodes to {name}.json: a format change must be deliberate"
        );
        println!("{name}: {} bytes: {}", bytes.len(), section_bytes(&bytes));
        // The committed file is what today's encoder writes for its source.
        assert!(
            encode(&rep) == bytes,
            "{name}: the encoder's output changed"
        );
        assert!(encode(&decoded) == bytes, "{name}: re-encoding changed");
        seen += 1;
    }
    assert_eq!(seen, 5);
}

// ---------------------------------------------------------------------------------------
// Invalid files, each named by the error it must produce.

/// The error's kind, as invalid fixture names spell it.
fn kind(e: &DecodeError) -> String {
    let place = |s: &Option<Tag>| s.map_or("header".to_string(), |t| t.to_string());
    let label = |what: &str| what.split(':').next().unwrap_or("").to_string();
    match e {
        DecodeError::Format { section, what } => {
            format!("format-{}-{}", place(section), label(what))
        }
        DecodeError::ChecksumMismatch { section, .. } => format!("checksum-{}", place(section)),
        DecodeError::UnsupportedVersion { .. } => "unsupported-version".to_string(),
        DecodeError::UnsupportedFeature { section, what } => {
            format!("unsupported-feature-{}-{}", place(section), label(what))
        }
        DecodeError::LimitsExceeded { what, .. } => format!("limits-{}", what.replace(' ', "-")),
        _ => "unknown".to_string(),
    }
}

/// Fields packed least significant bit first (spec §5.1): (value, bit count) pairs.
fn pack(fields: &[(u32, u32)]) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut at = 0usize;
    for &(value, count) in fields {
        for b in 0..count {
            if at % 8 == 0 {
                bytes.push(0);
            }
            if (value >> b) & 1 == 1 {
                *bytes.last_mut().unwrap() |= 1 << (at % 8);
            }
            at += 1;
        }
    }
    bytes
}

/// Raw payloads of a valid file's sections, in order.
fn payloads(bytes: &[u8]) -> Vec<(Tag, Vec<u8>)> {
    let c = read_container(bytes, &Limits::default()).unwrap();
    c.sections
        .iter()
        .map(|s| (s.tag, inflate(s, u64::MAX).unwrap()))
        .collect()
}

/// A file of uncompressed sections.
fn assemble(major: u16, minor: u16, flags: u32, sections: &[(Tag, Vec<u8>)]) -> Vec<u8> {
    let raw: Vec<RawSection> = sections
        .iter()
        .map(|(tag, raw)| RawSection {
            tag: *tag,
            flags: if [TAG_ELPS, TAG_ARCS, TAG_PNTS, TAG_CYCL].contains(tag) {
                SECTION_REQUIRED
            } else {
                0
            },
            raw_length: raw.len() as u32,
            stored: raw.clone(),
        })
        .collect();
    write_container(major, minor, flags, &raw).unwrap()
}

fn edit(sections: &[(Tag, Vec<u8>)], tag: Tag, f: impl Fn(&mut Vec<u8>)) -> Vec<(Tag, Vec<u8>)> {
    sections
        .iter()
        .map(|(t, raw)| {
            let mut raw = raw.clone();
            if *t == tag {
                f(&mut raw);
            }
            (*t, raw)
        })
        .collect()
}

/// Builds every invalid fixture from the golden representations.
fn invalid_fixtures() -> Vec<(&'static str, Vec<u8>)> {
    let sphere = encode(&sample::sphere());
    let lunes = encode(&sample::three_regions_two_junctions());
    let s = payloads(&sphere);
    let l = payloads(&lunes);
    let mut out: Vec<(&'static str, Vec<u8>)> = Vec::new();

    let mut bad_magic = sphere.clone();
    bad_magic[1] = b'X';
    out.push(("format-header-H1-bad-magic", bad_magic));
    out.push(("format-header-H1-too-short", sphere[..20].to_vec()));
    let mut header_crc = sphere.clone();
    header_crc[12] ^= 1;
    out.push(("checksum-header", header_crc));
    out.push(("unsupported-version-2.0", assemble(2, 0, 0, &s)));
    out.push(("unsupported-feature-header-H4-flag", assemble(1, 0, 1, &s)));
    out.push((
        "format-header-H5-truncated",
        lunes[..lunes.len() - 7].to_vec(),
    ));
    let mut trailing = lunes.clone();
    trailing.extend_from_slice(b"junk");
    out.push(("format-header-H5-trailing-bytes", trailing));
    let mut section_crc = assemble(1, 0, 0, &l);
    let n = section_crc.len();
    section_crc[n - 10] ^= 0x40; // inside CYCL's payload
    out.push(("checksum-CYCL", section_crc));
    let mut with_unknown = s.clone();
    with_unknown.push((Tag(*b"XTRA"), vec![1, 2, 3]));
    let mut required_unknown = assemble(1, 0, 0, &with_unknown);
    // Mark XTRA required: rebuild with the flag.
    {
        let c = read_container(&required_unknown, &Limits::default()).unwrap();
        let raw: Vec<RawSection> = c
            .sections
            .iter()
            .map(|v| RawSection {
                tag: v.tag,
                flags: if v.tag == Tag(*b"XTRA") {
                    SECTION_REQUIRED
                } else {
                    v.flags
                },
                raw_length: v.raw_length,
                stored: v.stored.to_vec(),
            })
            .collect();
        required_unknown = write_container(1, 0, 0, &raw).unwrap();
    }
    out.push(("unsupported-feature-XTRA-S6", required_unknown));
    let mut dup = s.clone();
    dup.push(s[1].clone());
    out.push(("format-ELPS-S5-duplicate", assemble(1, 0, 0, &dup)));
    let missing: Vec<_> = s.iter().filter(|(t, _)| *t != TAG_CYCL).cloned().collect();
    out.push(("format-CYCL-S7-missing", assemble(1, 0, 0, &missing)));
    // ELPS claims 10⁷ regions: refused before anything is allocated.
    out.push((
        "limits-regions",
        assemble(
            1,
            0,
            0,
            &edit(&s, TAG_ELPS, |raw| {
                raw[0] = 252;
                raw.splice(1..1, 10_000_000u32.to_le_bytes());
            }),
        ),
    ));
    // PNTS claims 2 GiB once inflated.
    {
        let c = read_container(&lunes, &Limits::default()).unwrap();
        let raw: Vec<RawSection> = c
            .sections
            .iter()
            .map(|v| RawSection {
                tag: v.tag,
                flags: v.flags
                    | if v.tag == TAG_PNTS {
                        SECTION_DEFLATE
                    } else {
                        0
                    },
                raw_length: if v.tag == TAG_PNTS {
                    1 << 31
                } else {
                    v.raw_length
                },
                stored: v.stored.to_vec(),
            })
            .collect();
        out.push((
            "limits-inflated-bytes",
            write_container(1, 0, 0, &raw).unwrap(),
        ));
    }
    // A DEFLATE stream that inflates to more than its raw length.
    {
        let c = read_container(&lunes, &Limits::default()).unwrap();
        let raw: Vec<RawSection> = c
            .sections
            .iter()
            .map(|v| {
                let mut r = RawSection {
                    tag: v.tag,
                    flags: v.flags,
                    raw_length: v.raw_length,
                    stored: v.stored.to_vec(),
                };
                if v.tag == TAG_PNTS {
                    let big = RawSection::compressed(TAG_PNTS, true, &vec![0u8; 4000]).unwrap();
                    r.flags = big.flags;
                    r.stored = big.stored;
                    r.raw_length = 100;
                }
                r
            })
            .collect();
        out.push((
            "format-PNTS-S8-inflates-past-raw-length",
            write_container(1, 0, 0, &raw).unwrap(),
        ));
    }
    // ELPS of the sphere: count, variant, centre 12, rotation 16, radii 12, sign 1.
    out.push((
        "format-ELPS-E2-radius-not-positive",
        assemble(
            1,
            0,
            0,
            &edit(&s, TAG_ELPS, |raw| {
                raw[34..38].copy_from_slice(&(-1.5f32).to_le_bytes())
            }),
        ),
    ));
    out.push((
        "format-ELPS-E1-nan-center",
        assemble(
            1,
            0,
            0,
            &edit(&s, TAG_ELPS, |raw| {
                raw[2..6].copy_from_slice(&f32::NAN.to_le_bytes())
            }),
        ),
    ));
    out.push((
        "format-ELPS-E3-rotation-not-normalised",
        assemble(
            1,
            0,
            0,
            &edit(&s, TAG_ELPS, |raw| {
                raw[26..30].copy_from_slice(&0.9f32.to_le_bytes())
            }),
        ),
    ));
    out.push((
        "format-ELPS-E0-unknown-precision",
        assemble(1, 0, 0, &edit(&s, TAG_ELPS, |raw| raw[1] = 7)),
    ));
    // ARCS of the lunes: count 3; arc 0 = closed 0, length 5, codes 0 0 0 0 0.
    out.push((
        "format-ARCS-A3-reference-before-use",
        assemble(
            1,
            0,
            0,
            &edit(&l, TAG_ARCS, |raw| {
                assert_eq!(raw[..3], [3, 0, 5]);
                raw[4] = 9;
            }),
        ),
    ));
    // CYCL of the lunes: regions 3; region 0: 1 cycle, outer 1, 2 refs: 0 (arc 0), 3 (arc 1
    // reversed). Make the second ref arc 0 forward again.
    out.push((
        "format-CYCL-C5-arc-used-twice",
        assemble(1, 0, 0, &edit(&l, TAG_CYCL, |raw| raw[5] = 0)),
    ));
    // Split region 0's cycle into two one-arc cycles (the second not outer): neither closes.
    out.push((
        "format-CYCL-C4-cycle-not-closed",
        assemble(
            1,
            0,
            0,
            &edit(&l, TAG_CYCL, |raw| {
                raw.splice(1..6, [2, 1, 1, 0, 0, 1, 3]);
            }),
        ),
    ));
    // PNTS of the lunes: count 11, bits 14, min 24, max 24, then the residual stream's
    // length (one byte here) at offset 50 and the stream.
    let with_stream = |stream: Vec<u8>| {
        edit(&l, TAG_PNTS, move |raw| {
            assert!(raw[50] < 251);
            raw.truncate(50);
            raw.push(stream.len() as u8);
            raw.extend_from_slice(&stream);
        })
    };
    // The first residual escaped (20 zero bits, then 32 bits): zig-zag 1 = −1, predicted
    // from 0.
    out.push((
        "format-PNTS-P8-grid-index-out-of-range",
        assemble(1, 0, 0, &with_stream(pack(&[(0, 20), (1, 32), (0, 4)]))),
    ));
    out.push((
        "format-PNTS-P7-stream-ends-early",
        assemble(
            1,
            0,
            0,
            &edit(&l, TAG_PNTS, |raw| {
                let n = usize::from(raw[50]);
                raw[50] = (n - 1) as u8;
                raw.pop();
            }),
        ),
    ));
    out.push((
        "format-PNTS-P9-bits-after-the-residuals",
        assemble(
            1,
            0,
            0,
            &edit(&l, TAG_PNTS, |raw| {
                raw[50] += 1;
                raw.push(0x80);
            }),
        ),
    ));
    // A quantised sphere (ELPS variant 2): count 1, variant 2, stream length, stream.
    let quantised = |radius_y: u32, rotation: [u32; 3], extra: &[u8]| {
        let mut stream = pack(&[
            (0, 1),    // positive
            (0xfc, 8), // e = −4: steps of 1/16
            (7, 5),    // centre width
            (16, 7),   // 0.5 = 8/16, zig-zag 16
            (7, 7),    // −0.25 = −4/16, zig-zag 7
            (64, 7),   // 2 = 32/16, zig-zag 64
            (5, 5),    // radii width
            (24, 5),   // 1.5 = 24/16
            (radius_y, 5),
            (24, 5),
            (3, 2), // w is the largest component
            (8, 5), // s = 8: steps of 1/256
            (9, 5), // rotation width
            (rotation[0], 9),
            (rotation[1], 9),
            (rotation[2], 9),
        ]);
        stream.extend_from_slice(extra);
        let mut raw = vec![1, 2, stream.len() as u8];
        raw.extend_from_slice(&stream);
        edit(&s, TAG_ELPS, move |payload| *payload = raw.clone())
    };
    // The well-formed one decodes (a check of the recipe, not a fixture).
    let ok = format::decode(
        &assemble(1, 0, 0, &quantised(24, [0; 3], &[])),
        &Limits::default(),
    )
    .expect("the quantised sphere decodes");
    assert_eq!(ok.ellipsoids, sample::sphere().ellipsoids);
    out.push((
        "format-ELPS-E2-quantised-radius-zero",
        assemble(1, 0, 0, &quantised(0, [0; 3], &[])),
    ));
    // Components 200/256 and 200/256 (zig-zag 400): squares sum to 1.22.
    out.push((
        "format-ELPS-E4-quantised-rotation-exceeds-one",
        assemble(1, 0, 0, &quantised(24, [400, 400, 0], &[])),
    ));
    out.push((
        "format-ELPS-E5-bits-after-the-ellipsoid",
        assemble(1, 0, 0, &quantised(24, [0; 3], &[0])),
    ));
    out.push((
        "format-PNTS-P5-bits-out-of-range",
        assemble(1, 0, 0, &edit(&l, TAG_PNTS, |raw| raw[1] = 30)),
    ));
    out.push((
        "format-PNTS-P4-point-count-mismatch",
        assemble(1, 0, 0, &edit(&l, TAG_PNTS, |raw| raw[0] = 10)),
    ));
    out.push((
        "format-META-S9-bytes-after-the-fields",
        assemble(1, 0, 0, &edit(&s, TAG_META, |raw| raw.push(0))),
    ));
    out
}

#[test]
fn invalid_files_give_the_error_their_name_says() {
    let dir = fixtures().join("invalid");
    if regenerate() {
        std::fs::create_dir_all(&dir).unwrap();
        for (name, bytes) in invalid_fixtures() {
            std::fs::write(dir.join(format!("{name}.ellip")), bytes).unwrap();
        }
    }
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("ellip") {
            continue;
        }
        let name = path.file_stem().unwrap().to_str().unwrap().to_string();
        let bytes = std::fs::read(&path).unwrap();
        let err = format::decode(&bytes, &Limits::default())
            .expect_err(&format!("{name} must not decode"));
        let k = kind(&err);
        assert!(
            name == k || name.starts_with(&format!("{k}-")),
            "{name} gave {k}: {err}"
        );
        checked += 1;
    }
    assert_eq!(checked, invalid_fixtures().len());
    // The committed files are the ones the generator builds.
    for (name, bytes) in invalid_fixtures() {
        assert_eq!(
            std::fs::read(dir.join(format!("{name}.ellip"))).unwrap(),
            bytes,
            "{name}"
        );
    }
}

#[test]
fn version_rules() {
    let s = payloads(&encode(&sample::sphere()));
    // A higher minor version is read; what it appends to a section is ignored (after 1.1's
    // remesh hint, here none).
    let newer = assemble(
        1,
        7,
        0,
        &edit(&s, TAG_META, |raw| raw.extend_from_slice(&[0, 1, 2, 3])),
    );
    assert_eq!(
        format::decode(&newer, &Limits::default()).unwrap(),
        sample::sphere()
    );
    // 1.1 adds the remesh hint to META: there it must be, and nothing after it.
    let hinted = |minor, tail: &[u8]| {
        let bytes = assemble(1, minor, 0, &edit(&s, TAG_META, |raw| raw.extend(tail)));
        format::decode(&bytes, &Limits::default()).map(|rep| rep.metadata.remesh_hint)
    };
    assert_eq!(hinted(1, &[1, 37]), Ok(Some(37)));
    assert_eq!(hinted(1, &[0]), Ok(None));
    for (minor, tail) in [(1, &[][..]), (1, &[2]), (1, &[1])] {
        assert!(
            matches!(
                hinted(minor, tail),
                Err(DecodeError::Format { what, .. }) if what.starts_with("M0")
            ),
            "1.{minor} META + {tail:?}"
        );
    }
    for (minor, tail) in [(1, &[1, 37, 0][..]), (0, &[1, 37])] {
        assert!(
            matches!(
                hinted(minor, tail),
                Err(DecodeError::Format { what, .. }) if what.starts_with("S9")
            ),
            "1.{minor} META + {tail:?}"
        );
    }
    // A file is written with the lowest minor that holds it.
    assert_eq!(
        format::inspect(&encode(&sample::sphere()), &Limits::default())
            .unwrap()
            .minor,
        0
    );
    let hinted_file = encode(&sample::two_hemispheres_hinted());
    assert_eq!(
        format::inspect(&hinted_file, &Limits::default())
            .unwrap()
            .minor,
        1
    );
    // Unknown optional sections are skipped.
    let mut extra = s.clone();
    extra.insert(0, (Tag(*b"xtra"), vec![9; 40]));
    let bytes = assemble(1, 0, 0, &extra);
    let raw = read_container(&bytes, &Limits::default()).unwrap();
    assert_eq!(raw.sections[0].flags & SECTION_REQUIRED, 0);
    assert_eq!(
        format::decode(&bytes, &Limits::default()).unwrap(),
        sample::sphere()
    );
    let summary = format::inspect(&bytes, &Limits::default()).unwrap();
    assert!(!summary.sections[0].known);
    // Major 0 and 2 are refused.
    for major in [0, 2] {
        assert_eq!(
            format::decode(&assemble(major, 0, 0, &s), &Limits::default()),
            Err(DecodeError::UnsupportedVersion { major, minor: 0 })
        );
    }
}

// ---------------------------------------------------------------------------------------
// Hostile bytes

#[test]
fn every_truncation_and_every_bit_flip_is_an_error() {
    for (name, rep) in sample::golden() {
        let bytes = encode(&rep);
        for n in 0..bytes.len() {
            assert!(
                format::decode(&bytes[..n], &Limits::default()).is_err(),
                "{name}[..{n}]"
            );
        }
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut b = bytes.clone();
                b[i] ^= 1 << bit;
                // A flip is caught by a CRC, the magic, or the length; never decoded.
                assert!(
                    format::decode(&b, &Limits::default()).is_err(),
                    "{name} byte {i} bit {bit}"
                );
            }
        }
    }
}

#[test]
fn limits_are_enforced_before_allocation() {
    let rep = sample::lunes(6, 100, 0.0);
    let bytes = encode(&rep);
    let tight = |f: fn(&mut Limits)| {
        let mut l = Limits::default();
        f(&mut l);
        format::decode(&bytes, &l).unwrap_err()
    };
    let what = |e: DecodeError| match e {
        DecodeError::LimitsExceeded {
            what,
            requested,
            max,
        } => (what, requested, max),
        other => panic!("{other}"),
    };
    assert_eq!(what(tight(|l| l.max_file_bytes = 100)).0, "file bytes");
    assert_eq!(what(tight(|l| l.max_points = 601)), ("points", 602, 601));
    assert_eq!(what(tight(|l| l.max_arcs = 5)), ("arcs", 6, 5));
    assert_eq!(what(tight(|l| l.max_regions = 5)), ("regions", 6, 5));
    assert_eq!(what(tight(|l| l.max_arc_points = 611)).0, "arc points");
    assert_eq!(
        what(tight(|l| l.max_cycle_refs = 11)).0,
        "cycle arc references"
    );
    assert_eq!(what(tight(|l| l.max_cycles = 5)).0, "cycles");
    assert_eq!(what(tight(|l| l.max_sections = 4)).0, "sections");
    assert_eq!(
        what(tight(|l| l.max_inflated_bytes = 100)).0,
        "inflated bytes"
    );
    assert!(format::decode(&bytes, &Limits::default()).is_ok());
}

#[test]
fn fuzz_regressions_do_not_panic() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/regressions");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return;
    };
    for entry in entries {
        let path = entry.unwrap().path();
        if path.is_file() {
            let bytes = std::fs::read(&path).unwrap();
            // Must return (either way) without panicking, under both limit sets.
            let _ = format::decode(&bytes, &Limits::small());
            let _ = format::decode(&bytes, &Limits::default());
            let _ = format::inspect(&bytes, &Limits::small());
        }
    }
}

// ---------------------------------------------------------------------------------------
// Property tests

fn raw_ellipsoid() -> impl Strategy<Value = RawEllipsoid> {
    (
        prop::array::uniform3(-100.0..100.0f64),
        prop::array::uniform4(-1.0..1.0f64),
        prop::array::uniform3(0.01..2000.0f64),
        any::<bool>(),
    )
        .prop_map(|(center, rotation, radii, negative)| RawEllipsoid {
            center,
            rotation,
            radii,
            negative,
        })
}

fn piece() -> impl Strategy<Value = Piece> {
    prop_oneof![
        (2u8..6, 0u8..20).prop_map(|(lunes, interior)| Piece::Lunes { lunes, interior }),
        (3u8..30, any::<bool>()).prop_map(|(points, border)| Piece::Loop { points, border }),
        Just(Piece::Whole),
    ]
}

fn recipe() -> impl Strategy<Value = Recipe> {
    (
        prop::collection::vec(raw_ellipsoid(), 0..5),
        prop::collection::vec(prop::array::uniform3(-50.0..50.0f64), 0..40),
        prop::collection::vec(piece(), 1..6),
        (
            any::<u32>(),
            any::<u32>(),
            prop::option::of(0.0..1.0f64),
            prop::option::of(any::<u32>()),
            prop::option::of(any::<u64>()),
        ),
    )
        .prop_map(
            |(ellipsoids, coordinates, pieces, (v, f, err, sv, hint))| Recipe {
                ellipsoids,
                coordinates,
                pieces,
                metadata: Metadata {
                    source_vertices: u64::from(v),
                    source_faces: u64::from(f),
                    simplify_tolerance: None,
                    measured_error: err,
                    measured_hausdorff: err.map(|e| 3.0 * e),
                    suggested_vertices: sv.map(u64::from),
                    remesh_hint: hint,
                },
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_representations_round_trip(recipe in recipe(), bits in 1u8..=24) {
        let rep = sample::build(&recipe);
        prop_assert!(rep.validate().is_ok());
        check_round_trip(&rep, &EncodeOptions { bits });
    }

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let _ = format::decode(&bytes, &Limits::small());
        // With a valid header in front, the section parser sees the bytes too.
        let mut file = encode(&sample::sphere())[..HEADER_LEN].to_vec();
        file.extend_from_slice(&bytes);
        let total = file.len() as u64;
        file[16..24].copy_from_slice(&total.to_le_bytes());
        let crc = crc32fast_hash(&file[..24]);
        file[24..28].copy_from_slice(&crc.to_le_bytes());
        let _ = format::decode(&file, &Limits::small());
    }
}

/// CRC-32 (IEEE), bit by bit: the test does not lean on the codec's own dependency.
fn crc32fast_hash(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

// ---------------------------------------------------------------------------------------
// Sizes (run with `--nocapture` to see the table; spec appendix B quotes it)

fn section_bytes(bytes: &[u8]) -> String {
    let s = format::inspect(bytes, &Limits::default()).unwrap();
    s.sections
        .iter()
        .map(|x| format!("{} {}/{}", x.tag, x.stored_bytes, x.raw_bytes))
        .collect::<Vec<_>>()
        .join(", ")
}

#[test]
fn sizes_shrink_with_fewer_bits_and_with_simplification() {
    // Eight lunes, 400 points per arc wobbling like a mesh's edge path (edge ≈ 0.008,
    // wobble ≤ 0.003) on a unit sphere: bounding-box diagonal ≈ 3.46.
    let dense = sample::lunes(8, 400, 0.003);
    let diagonal = 2.0 * 3f64.sqrt();
    println!("points  tolerance/diag  bits  bytes  error bound/diag  sections (stored/raw)");
    let mut previous_tolerance_size = usize::MAX;
    for rel in [0.0, 2.5e-4, 1e-3, 4e-3] {
        let mut rep = dense.clone();
        if rel > 0.0 {
            rep.simplify_arcs(rel * diagonal);
        }
        let mut previous = 0;
        for bits in [10, 12, 14, 16, 20] {
            let bytes = format::encode(&rep, &EncodeOptions { bits }).unwrap();
            let summary = format::inspect(&bytes, &Limits::default()).unwrap();
            println!(
                "{:6}  {:14.1e}  {bits:4}  {:5}  {:16.2e}  {}",
                rep.points.len(),
                rel,
                bytes.len(),
                summary.error_bound / diagonal,
                section_bytes(&bytes)
            );
            assert!(bytes.len() >= previous, "more bits, fewer bytes?");
            previous = bytes.len();
        }
        let size = format::encode(&rep, &EncodeOptions::default())
            .unwrap()
            .len();
        assert!(size < previous_tolerance_size);
        previous_tolerance_size = size;
    }
    // Ellipsoid storage: surface displacement relative to the diagonal, in a file whose
    // points set the error bound (quantised within it when 31-bit fields reach it, else
    // binary32 within it, else binary64).
    let mut simplified = dense.clone();
    simplified.simplify_arcs(1e-3 * diagonal);
    for (name, e) in [
        ("lune", dense.ellipsoids[1]),
        (
            "flat r=1e3·diag",
            Ellipsoid {
                radii: DVec3::splat(1e3 * diagonal),
                center: DVec3::new(0.0, 0.0, -1e3 * diagonal),
                ..dense.ellipsoids[0]
            },
        ),
        (
            "flat r=10·diag",
            Ellipsoid {
                radii: DVec3::splat(10.0 * diagonal),
                center: DVec3::new(0.0, 0.0, -10.0 * diagonal),
                ..dense.ellipsoids[0]
            },
        ),
    ] {
        let mut rep = simplified.clone();
        rep.ellipsoids[0] = e;
        let decoded = format::decode(&encode(&rep), &Limits::default())
            .unwrap()
            .ellipsoids[0];
        let single = format::encode(&simplified, &EncodeOptions::default())
            .unwrap()
            .len();
        let worst = (0..200)
            .map(|i| {
                let t = i as f64 * 0.61;
                let u = DVec3::new(
                    t.cos() * (0.3 * t).sin(),
                    t.sin() * (0.3 * t).sin(),
                    (0.3 * t).cos(),
                );
                (e.from_unit_sphere(u) - decoded.from_unit_sphere(u)).length()
            })
            .fold(0.0, f64::max);
        let summary = format::inspect(&encode(&rep), &Limits::default()).unwrap();
        println!(
            "{name}: file {} bytes (+{}), ellipsoids quantised {}/8, binary32 {}/8, its surface moved ≤ {:.2e}·diag (bound {:.2e})",
            summary.total_bytes,
            summary.total_bytes as i64 - single as i64,
            summary.quantised_ellipsoids,
            summary.f32_ellipsoids,
            worst / diagonal,
            summary.error_bound / diagonal
        );
        assert!(worst <= summary.error_bound);
    }
}
