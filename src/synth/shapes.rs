//! Meshes of simple shapes whose area, volume, topology and curvature are known exactly.
//!
//! Every builder returns a valid, consistently oriented [`Mesh`] whose faces point outward
//! (the [`bowl`] alone faces its centre, by design), closed where the shape is closed, without
//! degenerate faces, and with every vertex on the analytic surface up to rounding.
//!
//! Spheres come from a subdivided icosahedron that has a vertex on each pole: from one
//! subdivision on, its edges include the equator exactly (the midpoints of the edges crossing
//! the equator have z = 0 in exact arithmetic, and so do all their descendants), so
//! [`hemisphere`], [`bowl`] and the caps of [`capsule`] are whole triangles of the same
//! icosphere, with a clean boundary and no slivers.
//!
//! Parametric shapes ([`torus`], [`cylinder`], [`cube`], [`grid`]) split every grid quad along
//! the same diagonal, so each vertex's one-ring is centrally symmetric, which keeps curvature
//! estimates on them accurate.
//!
//! # Limits
//!
//! No builder makes more than [`MAX_FACES`] faces; for the icosphere family that means at
//! most [`MAX_SUBDIVISIONS`] subdivisions. Asking for more is a programmer error and panics,
//! as does a non-finite or non-positive size (see each function's `# Panics`).

use super::EllipsoidSpec;
use crate::mesh::Mesh;
use glam::DVec3;
use std::collections::HashMap;
use std::f64::consts::TAU;

/// Most faces a builder makes (2²³ = 8,388,608).
pub const MAX_FACES: usize = 1 << 23;

/// Most subdivisions of the icosphere family ([`icosphere`], [`ellipsoid`], [`hemisphere`],
/// [`bowl`], and the caps of [`capsule`]): 20·4⁹ = 5,242,880 faces.
pub const MAX_SUBDIVISIONS: u32 = 9;

/// A sphere of `radius` around the origin, from an icosahedron (a vertex on each pole)
/// subdivided `subdivisions` times with its new vertices pushed onto the sphere:
/// 20·4ˢ faces and 10·4ˢ + 2 vertices.
///
/// # Panics
/// If `radius` is not finite and positive, or `subdivisions > MAX_SUBDIVISIONS`.
pub fn icosphere(radius: f64, subdivisions: u32) -> Mesh {
    check_size("radius", radius);
    check_subdivisions(subdivisions);
    let (positions, faces) = unit_icosphere(subdivisions);
    build(positions.into_iter().map(|p| p * radius).collect(), faces)
}

/// The ellipsoid `spec` describes (the unit sphere scaled by its radii, rotated, then moved
/// to its centre), as the image of [`icosphere`]`(1, subdivisions)`; 20·4ˢ faces. The
/// rotation is normalised first.
///
/// # Panics
/// If a radius is not finite and positive, the centre is not finite, the rotation is not
/// finite or is zero, or `subdivisions > MAX_SUBDIVISIONS`.
pub fn ellipsoid(spec: &EllipsoidSpec, subdivisions: u32) -> Mesh {
    check_size("radius x", spec.radii.x);
    check_size("radius y", spec.radii.y);
    check_size("radius z", spec.radii.z);
    assert!(spec.center.is_finite(), "ellipsoid centre must be finite");
    assert!(
        spec.rotation.is_finite() && spec.rotation.length_squared() > 0.0,
        "ellipsoid rotation must be a finite non-zero quaternion"
    );
    check_subdivisions(subdivisions);
    let rotation = spec.rotation.normalize();
    let (positions, faces) = unit_icosphere(subdivisions);
    let positions = positions
        .into_iter()
        .map(|p| spec.center + rotation * (spec.radii * p))
        .collect();
    build(positions, faces)
}

/// A torus around the z axis: the circle of radius `minor` centred `major` from the axis,
/// swept around it. `segments_major` vertices around the axis times `segments_minor` around
/// the tube; 2·segments_major·segments_minor faces, genus 1.
///
/// # Panics
/// If `minor` is not finite and positive, `major` is not finite or not greater than `minor`
/// (the torus would cross itself), a segment count is below 3, or there would be more than
/// [`MAX_FACES`] faces.
pub fn torus(major: f64, minor: f64, segments_major: u32, segments_minor: u32) -> Mesh {
    check_size("minor radius", minor);
    assert!(
        major.is_finite() && major > minor,
        "torus major radius must be finite and greater than the minor radius"
    );
    check_segments(segments_major);
    check_segments(segments_minor);
    check_faces(2 * u128::from(segments_major) * u128::from(segments_minor));
    let (nu, nv) = (segments_major as usize, segments_minor as usize);
    let mut positions = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        let (su, cu) = (TAU * i as f64 / nu as f64).sin_cos();
        for j in 0..nv {
            let (sv, cv) = (TAU * j as f64 / nv as f64).sin_cos();
            let rho = major + minor * cv;
            positions.push(DVec3::new(rho * cu, rho * su, minor * sv));
        }
    }
    let index = |i: usize, j: usize| ((i % nu) * nv + j % nv) as u32;
    let mut faces = Vec::with_capacity(2 * nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            // (∂/∂u × ∂/∂v) points away from the tube's core circle.
            push_quad(
                &mut faces,
                [
                    index(i, j),
                    index(i + 1, j),
                    index(i + 1, j + 1),
                    index(i, j + 1),
                ],
            );
        }
    }
    build(positions, faces)
}

/// An open tube of `radius` along the z axis, from z = −height/2 to height/2:
/// `segments_along + 1` rings of `segments_around` vertices; two boundary loops.
///
/// # Panics
/// If `radius` or `height` is not finite and positive, `segments_around < 3`,
/// `segments_along < 1`, or there would be more than [`MAX_FACES`] faces.
pub fn cylinder(radius: f64, height: f64, segments_around: u32, segments_along: u32) -> Mesh {
    check_size("radius", radius);
    check_size("height", height);
    check_segments(segments_around);
    assert!(
        segments_along >= 1,
        "cylinder needs at least one segment along"
    );
    check_faces(2 * u128::from(segments_around) * u128::from(segments_along));
    let (n, m) = (segments_around as usize, segments_along as usize);
    let mut positions = Vec::with_capacity(n * (m + 1));
    for j in 0..=m {
        let z = height * (j as f64 / m as f64 - 0.5);
        for i in 0..n {
            let (s, c) = (TAU * i as f64 / n as f64).sin_cos();
            positions.push(DVec3::new(radius * c, radius * s, z));
        }
    }
    let mut faces = Vec::with_capacity(2 * n * m);
    for j in 0..m {
        let ring = (j * n) as u32;
        push_band(
            &mut faces,
            n,
            |i| ring + i as u32,
            |i| ring + (n + i) as u32,
        );
    }
    build(positions, faces)
}

/// A closed capsule: a tube of `radius` and `length` along the z axis, centred on the
/// origin, closed by two hemispheres. The caps are halves of an icosphere at the smallest
/// subdivision level (at least 1) whose equator has `segments` or more edges, so the tube
/// has 10·2ᵏ edges around (k ≥ 0); its rings are spaced about as far apart as its vertices
/// around (no more than keeps the capsule within [`MAX_FACES`]). A `length` of 0 gives that
/// icosphere.
///
/// # Panics
/// If `radius` is not finite and positive, `length` is not finite and non-negative, or more
/// than 10·2⁸ segments (the equator at [`MAX_SUBDIVISIONS`]) are asked for.
pub fn capsule(radius: f64, length: f64, segments: u32) -> Mesh {
    check_size("radius", radius);
    assert!(
        length.is_finite() && length >= 0.0,
        "capsule length must be finite and non-negative"
    );
    let subdivisions = (1..=MAX_SUBDIVISIONS)
        .find(|&s| equator_edge_count(s) >= segments as usize)
        .unwrap_or_else(|| panic!("a capsule has at most {} segments", equator_edge_count(9)));
    let (unit, sphere_faces) = unit_icosphere(subdivisions);
    if length == 0.0 {
        return build(unit.into_iter().map(|p| p * radius).collect(), sphere_faces);
    }
    let around = equator_edge_count(subdivisions);
    let spacing = radius * TAU / around as f64;
    // Ring intervals along the tube, capped so the face count stays bounded.
    let max_rings = (MAX_FACES - sphere_faces.len()) / (2 * around);
    let rings = ((length / spacing).round() as usize).clamp(1, max_rings);

    let half = DVec3::new(0.0, 0.0, 0.5 * length);
    let mut positions = Vec::with_capacity(unit.len() + (rings + 1) * around);
    // Off-equator vertices keep their icosphere index order, shifted to their cap.
    let mut cap_index = vec![u32::MAX; unit.len()];
    for (v, &p) in unit.iter().enumerate() {
        if p.z != 0.0 {
            cap_index[v] = positions.len() as u32;
            positions.push(p * radius + half * p.z.signum());
        }
    }
    // Equator vertices by angle, then one ring per level from the bottom cap to the top one.
    let equator = equator_by_angle(&unit);
    let ring_start = positions.len();
    for k in 0..=rings {
        let z = length * (k as f64 / rings as f64 - 0.5);
        for &v in &equator {
            let p = unit[v as usize] * radius;
            positions.push(DVec3::new(p.x, p.y, z));
        }
    }
    let ring_vertex = |k: usize, i: usize| (ring_start + k * around + i % around) as u32;
    // Where each equator vertex sits in its ring.
    let mut slot = vec![usize::MAX; unit.len()];
    for (i, &v) in equator.iter().enumerate() {
        slot[v as usize] = i;
    }
    let mut faces = Vec::with_capacity(sphere_faces.len() + 2 * rings * around);
    for face in &sphere_faces {
        let top = face.iter().map(|&v| unit[v as usize].z).sum::<f64>() > 0.0;
        faces.push(face.map(|v| match cap_index[v as usize] {
            u32::MAX if top => ring_vertex(rings, slot[v as usize]),
            u32::MAX => ring_vertex(0, slot[v as usize]),
            i => i,
        }));
    }
    for k in 0..rings {
        push_band(
            &mut faces,
            around,
            |i| ring_vertex(k, i),
            |i| ring_vertex(k + 1, i),
        );
    }
    build(positions, faces)
}

/// The upper half (z ≥ 0) of [`icosphere`]`(radius, subdivisions)`, facing outward:
/// 10·4ˢ faces and one boundary loop of 10·2ˢ⁻¹ edges on the equator.
///
/// # Panics
/// If `radius` is not finite and positive, or `subdivisions` is 0 (the icosahedron has no
/// equator) or above [`MAX_SUBDIVISIONS`].
pub fn hemisphere(radius: f64, subdivisions: u32) -> Mesh {
    half_sphere(radius, subdivisions, true)
}

/// The lower half (z ≤ 0) of [`icosphere`]`(radius, subdivisions)` seen from inside: a
/// concave cap whose faces point toward the sphere's centre. 10·4ˢ faces, one boundary loop
/// on the equator.
///
/// # Panics
/// As [`hemisphere`].
pub fn bowl(radius: f64, subdivisions: u32) -> Mesh {
    half_sphere(radius, subdivisions, false)
}

/// A closed axis-aligned cube with edges of length `size`, centred on the origin; each side
/// is a `subdivisions`×`subdivisions` grid: 12·s² faces and 6·s² + 2 vertices.
///
/// # Panics
/// If `size` is not finite and positive, `subdivisions` is 0, or there would be more than
/// [`MAX_FACES`] faces.
pub fn cube(size: f64, subdivisions: u32) -> Mesh {
    check_size("size", size);
    assert!(subdivisions >= 1, "cube needs at least one subdivision");
    check_faces(12 * u128::from(subdivisions) * u128::from(subdivisions));
    let s = subdivisions;
    let coordinate = |l: u32| size * (f64::from(l) / f64::from(s) - 0.5);
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut faces = Vec::with_capacity(12 * (s as usize).pow(2));
    // For each side: the fixed axis and its lattice value, and the two in-plane axes (u, w)
    // with u × w pointing outward.
    let sides: [(usize, u32, usize, usize); 6] = [
        (0, s, 1, 2),
        (0, 0, 2, 1),
        (1, s, 2, 0),
        (1, 0, 0, 2),
        (2, s, 0, 1),
        (2, 0, 1, 0),
    ];
    for (axis, value, u, w) in sides {
        let mut vertex = |i: u32, j: u32| {
            let mut lattice = [0u32; 3];
            lattice[axis] = value;
            lattice[u] = i;
            lattice[w] = j;
            *index.entry(lattice).or_insert_with(|| {
                positions.push(DVec3::from_array(lattice.map(coordinate)));
                (positions.len() - 1) as u32
            })
        };
        for i in 0..s {
            for j in 0..s {
                let quad = [
                    vertex(i, j),
                    vertex(i + 1, j),
                    vertex(i + 1, j + 1),
                    vertex(i, j + 1),
                ];
                push_quad(&mut faces, quad);
            }
        }
    }
    build(positions, faces)
}

/// A flat square of side `size` in the plane z = 0, centred on the origin, facing +z:
/// a `subdivisions`×`subdivisions` grid, 2·s² faces and (s + 1)² vertices.
///
/// # Panics
/// If `size` is not finite and positive, `subdivisions` is 0, or there would be more than
/// [`MAX_FACES`] faces.
pub fn grid(size: f64, subdivisions: u32) -> Mesh {
    check_size("size", size);
    assert!(subdivisions >= 1, "grid needs at least one subdivision");
    check_faces(2 * u128::from(subdivisions) * u128::from(subdivisions));
    let s = subdivisions as usize;
    let coordinate = |l: usize| size * (l as f64 / s as f64 - 0.5);
    let mut positions = Vec::with_capacity((s + 1) * (s + 1));
    for j in 0..=s {
        for i in 0..=s {
            positions.push(DVec3::new(coordinate(i), coordinate(j), 0.0));
        }
    }
    let index = |i: usize, j: usize| (j * (s + 1) + i) as u32;
    let mut faces = Vec::with_capacity(2 * s * s);
    for j in 0..s {
        for i in 0..s {
            push_quad(
                &mut faces,
                [
                    index(i, j),
                    index(i + 1, j),
                    index(i + 1, j + 1),
                    index(i, j + 1),
                ],
            );
        }
    }
    build(positions, faces)
}

/// One half of an icosphere: the upper one facing out, or the lower one facing in.
fn half_sphere(radius: f64, subdivisions: u32, upper: bool) -> Mesh {
    check_size("radius", radius);
    assert!(
        subdivisions >= 1,
        "a half sphere needs at least one subdivision"
    );
    check_subdivisions(subdivisions);
    let (unit, sphere_faces) = unit_icosphere(subdivisions);
    let mut index = vec![u32::MAX; unit.len()];
    let mut positions = Vec::with_capacity(unit.len() / 2 + equator_edge_count(subdivisions));
    let mut faces = Vec::with_capacity(sphere_faces.len() / 2);
    for face in &sphere_faces {
        // No face crosses the equator, so any non-zero z tells the side.
        let z: f64 = face.iter().map(|&v| unit[v as usize].z).sum();
        if (z > 0.0) != upper {
            continue;
        }
        let mut kept = face.map(|v| {
            let slot = &mut index[v as usize];
            if *slot == u32::MAX {
                *slot = positions.len() as u32;
                positions.push(unit[v as usize] * radius);
            }
            *slot
        });
        if !upper {
            kept.swap(1, 2);
        }
        faces.push(kept);
    }
    build(positions, faces)
}

/// Number of edges on the equator of the icosphere with `subdivisions ≥ 1`.
fn equator_edge_count(subdivisions: u32) -> usize {
    10 << (subdivisions - 1)
}

/// Indices of the vertices with z = 0, counter-clockwise seen from +z.
fn equator_by_angle(unit: &[DVec3]) -> Vec<u32> {
    let mut equator: Vec<(f64, u32)> = unit
        .iter()
        .enumerate()
        .filter(|(_, p)| p.z == 0.0)
        .map(|(v, p)| (p.y.atan2(p.x), v as u32))
        .collect();
    equator.sort_by(|a, b| a.0.total_cmp(&b.0));
    equator.into_iter().map(|(_, v)| v).collect()
}

/// The unit icosphere with a vertex on each pole, subdivided `subdivisions` times.
fn unit_icosphere(subdivisions: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    // Poles, an upper ring of five at z = h and a lower ring of five at z = −h, turned by
    // 36°. With h = 1/√5 and ρ = 2/√5 all 30 edges have the same length. The lower ring
    // uses exactly −h so that the midpoints of the band edges have z = 0 exactly.
    let h = 1.0 / 5f64.sqrt();
    let rho = 2.0 * h;
    let mut positions = vec![DVec3::Z];
    for k in 0..5 {
        let (s, c) = (TAU * f64::from(k) / 5.0).sin_cos();
        positions.push(DVec3::new(rho * c, rho * s, h));
    }
    for k in 0..5 {
        let (s, c) = (TAU * (f64::from(k) + 0.5) / 5.0).sin_cos();
        positions.push(DVec3::new(rho * c, rho * s, -h));
    }
    positions.push(-DVec3::Z);
    let upper = |k: u32| 1 + k % 5;
    let lower = |k: u32| 6 + k % 5;
    let mut faces = Vec::with_capacity(20 << (2 * subdivisions));
    for k in 0..5 {
        faces.push([0, upper(k), upper(k + 1)]);
        faces.push([upper(k), lower(k), upper(k + 1)]);
        faces.push([lower(k), lower(k + 1), upper(k + 1)]);
        faces.push([11, lower(k + 1), lower(k)]);
    }
    for _ in 0..subdivisions {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::with_capacity(faces.len() * 3 / 2);
        let mut finer = Vec::with_capacity(faces.len() * 4);
        for &[a, b, c] in &faces {
            let mut mid = |x: u32, y: u32| {
                *midpoint.entry((x.min(y), x.max(y))).or_insert_with(|| {
                    let p = (positions[x as usize] + positions[y as usize]).normalize();
                    positions.push(p);
                    (positions.len() - 1) as u32
                })
            };
            let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
            finer.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        faces = finer;
    }
    (positions, faces)
}

/// Splits the quad `[a, b, c, d]` (counter-clockwise) along its diagonal a–c.
fn push_quad(faces: &mut Vec<[u32; 3]>, [a, b, c, d]: [u32; 4]) {
    faces.push([a, b, c]);
    faces.push([a, c, d]);
}

/// Joins a lower ring to the ring above it, both of `n` vertices counter-clockwise seen from
/// above, with faces pointing away from the axis.
fn push_band(
    faces: &mut Vec<[u32; 3]>,
    n: usize,
    lower: impl Fn(usize) -> u32,
    upper: impl Fn(usize) -> u32,
) {
    for i in 0..n {
        let j = (i + 1) % n;
        push_quad(faces, [lower(i), lower(j), upper(j), upper(i)]);
    }
}

/// Wraps positions and faces that the builders made valid by construction.
fn build(positions: Vec<DVec3>, faces: Vec<[u32; 3]>) -> Mesh {
    Mesh::new(positions, faces)
        .unwrap_or_else(|e| panic!("shape sizes too large for finite coordinates: {e}"))
}

fn check_size(what: &str, value: f64) {
    assert!(
        value.is_finite() && value > 0.0,
        "{what} must be finite and positive, got {value}"
    );
}

fn check_subdivisions(subdivisions: u32) {
    assert!(
        subdivisions <= MAX_SUBDIVISIONS,
        "at most {MAX_SUBDIVISIONS} subdivisions, got {subdivisions}"
    );
}

fn check_segments(segments: u32) {
    assert!(segments >= 3, "at least 3 segments, got {segments}");
}

fn check_faces(count: u128) {
    assert!(
        count <= MAX_FACES as u128,
        "{count} faces is more than the {MAX_FACES} a shape may have"
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;
    use std::f64::consts::PI;

    /// Checks what every builder promises: consistent orientation, manifold, no degenerate
    /// faces (each face's doubled area above 1e-6 of its longest squared edge).
    fn assert_valid(mesh: &Mesh) {
        let t = mesh.topology();
        assert!(t.is_manifold(), "not manifold");
        assert!(t.is_consistently_oriented(), "not consistently oriented");
        assert_eq!(t.referenced_vertex_count(), mesh.vertex_count());
        for f in 0..mesh.face_count() {
            let [a, b, c] = mesh.corners(f);
            let longest = (b - a)
                .length_squared()
                .max((c - b).length_squared())
                .max((a - c).length_squared());
            assert!(
                mesh.face_area_vector(f).length() > 1e-6 * longest,
                "face {f} is a sliver"
            );
        }
    }

    /// Signed volume of the cones from the origin to the faces.
    fn volume_from_origin(mesh: &Mesh) -> f64 {
        (0..mesh.face_count())
            .map(|f| {
                let [a, b, c] = mesh.corners(f);
                a.dot(b.cross(c))
            })
            .sum::<f64>()
            / 6.0
    }

    fn relative_error(actual: f64, expected: f64) -> f64 {
        (actual - expected).abs() / expected.abs()
    }

    #[test]
    fn icosphere_counts_and_surface() {
        for s in 0..=4u32 {
            let r = 1.7;
            let m = icosphere(r, s);
            assert_eq!(m.face_count(), 20 << (2 * s));
            assert_eq!(m.vertex_count(), (10 << (2 * s)) + 2);
            assert_valid(&m);
            assert!(m.topology().is_closed());
            assert_eq!(m.genus(), Some(0));
            assert_eq!(m.topology().component_count(), 1);
            for p in m.positions() {
                assert!((p.length() - r).abs() < 1e-14 * r);
            }
            // Outward: every face normal agrees with the direction to its centroid.
            for f in 0..m.face_count() {
                assert!(m.face_normal(f).dot(m.face_centroid(f)) > 0.0);
            }
        }
    }

    #[test]
    fn icosphere_measures_approach_the_sphere() {
        // An inscribed polyhedron falls short of the sphere by O(edge²): under 0.3% at s = 5.
        let r = 2.0;
        let m = icosphere(r, 5);
        let volume = m.volume().unwrap();
        let exact = 4.0 / 3.0 * PI * r.powi(3);
        assert!(volume > 0.0 && volume < exact);
        assert!(relative_error(volume, exact) < 3e-3, "{volume} vs {exact}");
        let area = m.area();
        assert!(relative_error(area, 4.0 * PI * r * r) < 3e-3);
    }

    #[test]
    fn ellipsoid_lies_on_its_surface() {
        let spec = EllipsoidSpec {
            center: DVec3::new(1.0, -2.0, 0.5),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1),
            radii: DVec3::new(3.0, 1.5, 0.8),
        };
        let m = ellipsoid(&spec, 5);
        assert_eq!(m.face_count(), 20 << 10);
        assert_valid(&m);
        assert_eq!(m.genus(), Some(0));
        let inverse = spec.rotation.normalize().inverse();
        for &p in m.positions() {
            let unit = (inverse * (p - spec.center)) / spec.radii;
            assert!((unit.length() - 1.0).abs() < 1e-13);
        }
        let exact = 4.0 / 3.0 * PI * spec.radii.x * spec.radii.y * spec.radii.z;
        let volume = m.volume().unwrap();
        assert!(volume > 0.0 && relative_error(volume, exact) < 3e-3);
    }

    #[test]
    fn torus_topology_and_measures() {
        let (big, small) = (3.0, 1.0);
        let m = torus(big, small, 96, 48);
        assert_eq!(m.face_count(), 2 * 96 * 48);
        assert_eq!(m.vertex_count(), 96 * 48);
        assert_valid(&m);
        assert!(m.topology().is_closed());
        assert_eq!(m.genus(), Some(1));
        for p in m.positions() {
            let rho = p.x.hypot(p.y);
            assert!(((rho - big).hypot(p.z) - small).abs() < 1e-14 * big);
        }
        // Polygonal sections lose O(1/n²): (2π/48)²/6 + (2π/96)²/6 ≈ 0.36% of the volume.
        let volume = m.volume().unwrap();
        assert!(volume > 0.0);
        let volume_error = relative_error(volume, 2.0 * PI * PI * big * small * small);
        let area_error = relative_error(m.area(), 4.0 * PI * PI * big * small);
        assert!(volume_error < 4e-3, "{volume_error}");
        assert!(area_error < 4e-3, "{area_error}");
    }

    #[test]
    fn cylinder_is_an_open_outward_tube() {
        let (r, h) = (0.5, 3.0);
        let (n, m_along) = (40, 25);
        let m = cylinder(r, h, n, m_along);
        assert_eq!(m.face_count(), 2 * 40 * 25);
        assert_eq!(m.vertex_count(), 40 * 26);
        assert_valid(&m);
        assert!(!m.topology().is_closed());
        assert_eq!(m.topology().boundary_loops().len(), 2);
        assert_eq!(m.genus(), Some(0));
        for p in m.positions() {
            assert!((p.x.hypot(p.y) - r).abs() < 1e-15);
            assert!(p.z.abs() <= 0.5 * h);
        }
        for f in 0..m.face_count() {
            let c = m.face_centroid(f);
            assert!(m.face_normal(f).dot(DVec3::new(c.x, c.y, 0.0)) > 0.0);
        }
        // Exactly the prism's side area; close to 2πrh.
        let prism = f64::from(n) * 2.0 * r * (PI / f64::from(n)).sin() * h;
        assert!(relative_error(m.area(), prism) < 1e-12);
        assert!(relative_error(m.area(), 2.0 * PI * r * h) < 1.1e-3);
    }

    #[test]
    fn capsule_is_closed_and_on_its_surface() {
        let (r, l) = (0.8, 2.5);
        let m = capsule(r, l, 30);
        assert_valid(&m);
        assert!(m.topology().is_closed());
        assert_eq!(m.genus(), Some(0));
        // 30 segments round up to the 40-edge equator of the twice-subdivided icosphere.
        let around = m.positions().iter().filter(|p| p.z == 0.5 * l).count();
        assert_eq!(around, 40);
        for p in m.positions() {
            let axis = DVec3::new(0.0, 0.0, p.z.clamp(-0.5 * l, 0.5 * l));
            assert!(((*p - axis).length() - r).abs() < 1e-14);
        }
        let fine = capsule(r, l, 300);
        let volume = fine.volume().unwrap();
        let exact = PI * r * r * l + 4.0 / 3.0 * PI * r.powi(3);
        assert!(volume > 0.0 && relative_error(volume, exact) < 1e-3);
        let area = 2.0 * PI * r * l + 4.0 * PI * r * r;
        assert!(relative_error(fine.area(), area) < 1e-3);
        // No length: the icosphere.
        let ball = capsule(r, 0.0, 10);
        assert_eq!(ball.face_count(), 80);
        assert_eq!(ball.genus(), Some(0));
    }

    #[test]
    fn hemisphere_has_a_clean_equator() {
        for s in 1..=4u32 {
            let r = 1.3;
            let m = hemisphere(r, s);
            assert_eq!(m.face_count(), 10 << (2 * s));
            assert_valid(&m);
            assert_eq!(m.genus(), Some(0));
            let loops = m.topology().boundary_loops();
            assert_eq!(loops.len(), 1);
            assert_eq!(loops[0].len(), 10 << (s - 1));
            for &v in &loops[0] {
                assert_eq!(m.positions()[v as usize].z, 0.0);
            }
            for p in m.positions() {
                assert!(p.z >= 0.0 && (p.length() - r).abs() < 1e-14 * r);
            }
        }
        let r = 1.3_f64;
        let m = hemisphere(r, 5);
        // Outward: the cones to the centre fill the half ball.
        let volume = volume_from_origin(&m);
        assert!(relative_error(volume, 2.0 / 3.0 * PI * r.powi(3)) < 3e-3);
        assert!(relative_error(m.area(), 2.0 * PI * r * r) < 3e-3);
    }

    #[test]
    fn bowl_faces_its_centre() {
        let r = 0.9;
        let m = bowl(r, 4);
        assert_eq!(m.face_count(), 10 << 8);
        assert_valid(&m);
        assert_eq!(m.topology().boundary_loops().len(), 1);
        for p in m.positions() {
            assert!(p.z <= 0.0 && (p.length() - r).abs() < 1e-14 * r);
        }
        for f in 0..m.face_count() {
            assert!(m.face_normal(f).dot(m.face_centroid(f)) < 0.0);
        }
        assert!(relative_error(-volume_from_origin(&m), 2.0 / 3.0 * PI * r.powi(3)) < 1e-2);
    }

    #[test]
    fn cube_counts_and_exact_measures() {
        for s in 1..=5u32 {
            let size = 2.5;
            let m = cube(size, s);
            let s2 = (s * s) as usize;
            assert_eq!(m.face_count(), 12 * s2);
            assert_eq!(m.vertex_count(), 6 * s2 + 2);
            assert_valid(&m);
            assert!(m.topology().is_closed());
            assert_eq!(m.genus(), Some(0));
            assert!(relative_error(m.volume().unwrap(), size.powi(3)) < 1e-12);
            assert!(relative_error(m.area(), 6.0 * size * size) < 1e-12);
            for p in m.positions() {
                assert_eq!(p.abs().max_element(), 0.5 * size);
            }
        }
    }

    #[test]
    fn grid_is_flat_and_faces_up() {
        let m = grid(4.0, 10);
        assert_eq!(m.face_count(), 200);
        assert_eq!(m.vertex_count(), 121);
        assert_valid(&m);
        let loops = m.topology().boundary_loops();
        assert_eq!(loops.len(), 1);
        assert_eq!(loops[0].len(), 40);
        assert_eq!(m.genus(), Some(0));
        assert!(relative_error(m.area(), 16.0) < 1e-12);
        for f in 0..m.face_count() {
            assert_eq!(m.face_normal(f), DVec3::Z);
        }
        assert!(m.positions().iter().all(|p| p.z == 0.0));
    }

    #[test]
    #[should_panic(expected = "radius must be finite and positive")]
    fn rejects_non_positive_radius() {
        icosphere(0.0, 2);
    }

    #[test]
    #[should_panic(expected = "at most 9 subdivisions")]
    fn rejects_too_many_subdivisions() {
        icosphere(1.0, 10);
    }

    #[test]
    #[should_panic(expected = "faces is more than")]
    fn rejects_too_many_faces() {
        grid(1.0, u32::MAX);
    }

    #[test]
    #[should_panic(expected = "greater than the minor radius")]
    fn rejects_self_crossing_torus() {
        torus(1.0, 1.0, 8, 8);
    }

    #[test]
    #[should_panic(expected = "at least one subdivision")]
    fn hemisphere_needs_an_equator() {
        hemisphere(1.0, 0);
    }
}
