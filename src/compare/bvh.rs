//! A bounding volume hierarchy of triangles for exact closest-point queries.
//!
//! Binary, axis-aligned boxes, built top-down by splitting each node's triangles at the
//! median of their centroids along the longest axis of the centroids' box (so the depth is
//! at most ⌈log₂ n⌉ + 1), leaves of at most [`LEAF_SIZE`] triangles. A query walks the tree
//! nearer child first and skips every box farther than the best triangle found so far, so
//! the answer is exact: the same as testing every triangle.
//!
//! Our own rather than `parry3d` or `bvh`: those bring a second linear-algebra stack
//! (nalgebra) and work in f32 by default, while this is a couple of hundred lines on glam's
//! f64 vectors with a tie rule (smallest id) that makes the answer independent of the tree.

use super::triangle::closest_point_on_triangle;
use glam::DVec3;

/// Most triangles in a leaf.
pub const LEAF_SIZE: usize = 4;

/// The closest point of the indexed triangles to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// The closest point.
    pub point: DVec3,
    /// Its squared distance to the query point.
    pub distance_squared: f64,
    /// The id given with the triangle it lies on; among triangles at the same distance, the
    /// smallest id, so the answer does not depend on the tree's shape.
    pub id: u32,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    min: DVec3,
    max: DVec3,
    /// Leaf: first triangle; inner node: index of the left child (the right one follows it).
    first: u32,
    /// Number of triangles of a leaf; 0 for an inner node.
    count: u32,
}

/// A BVH over triangles, each with a caller-chosen id.
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    triangles: Vec<([DVec3; 3], u32)>,
}

impl Bvh {
    /// Builds the hierarchy of `triangles` (corners and id).
    pub fn build(triangles: Vec<([DVec3; 3], u32)>) -> Bvh {
        let mut bvh = Bvh {
            nodes: Vec::with_capacity(2 * triangles.len() / LEAF_SIZE + 1),
            triangles,
        };
        if !bvh.triangles.is_empty() {
            bvh.nodes.push(Node {
                min: DVec3::ZERO,
                max: DVec3::ZERO,
                first: 0,
                count: 0,
            });
            bvh.build_node(0, 0, bvh.triangles.len());
        }
        bvh
    }

    /// Number of triangles indexed.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether no triangle is indexed.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Fills node `node` with triangles `start..end`, splitting it while it has more than
    /// [`LEAF_SIZE`].
    fn build_node(&mut self, node: usize, start: usize, end: usize) {
        let slice = &mut self.triangles[start..end];
        let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let (mut cmin, mut cmax) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for (t, _) in slice.iter() {
            for &p in t {
                min = min.min(p);
                max = max.max(p);
            }
            let c = centroid(t);
            cmin = cmin.min(c);
            cmax = cmax.max(c);
        }
        let count = end - start;
        if count <= LEAF_SIZE {
            self.nodes[node] = Node {
                min,
                max,
                first: start as u32,
                count: count as u32,
            };
            return;
        }
        let extent = cmax - cmin;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        let mid = count / 2;
        slice.select_nth_unstable_by(mid, |(s, i), (t, j)| {
            centroid(s)[axis]
                .total_cmp(&centroid(t)[axis])
                .then(i.cmp(j))
        });
        let left = self.nodes.len();
        let placeholder = Node {
            min: DVec3::ZERO,
            max: DVec3::ZERO,
            first: 0,
            count: 0,
        };
        self.nodes.push(placeholder);
        self.nodes.push(placeholder);
        self.nodes[node] = Node {
            min,
            max,
            first: left as u32,
            count: 0,
        };
        self.build_node(left, start, start + mid);
        self.build_node(left + 1, start + mid, end);
    }

    /// The closest point of the indexed triangles to `p`; `None` when there are none.
    pub fn find_closest(&self, p: DVec3) -> Option<Hit> {
        let mut best = Hit {
            point: DVec3::ZERO,
            distance_squared: f64::INFINITY,
            id: u32::MAX,
        };
        self.walk(p, f64::INFINITY, |triangles| {
            for &(corners, id) in triangles {
                let q = closest_point_on_triangle(p, corners);
                let d2 = q.distance_squared(p);
                if d2 < best.distance_squared || (d2 == best.distance_squared && id < best.id) {
                    best = Hit {
                        point: q,
                        distance_squared: d2,
                        id,
                    };
                }
            }
            Some(best.distance_squared)
        });
        best.distance_squared.is_finite().then_some(best)
    }

    /// Whether some indexed triangle lies within `radius` of `p` (at a distance of at most
    /// `radius`). Stops at the first such triangle: for a point near the surface, one walk
    /// down the tree, where [`Bvh::find_closest`] must rule out every nearer box.
    pub fn is_within(&self, p: DVec3, radius: f64) -> bool {
        let r2 = radius * radius;
        let mut found = false;
        self.walk(p, r2, |triangles| {
            found = triangles.iter().any(|&(corners, _)| {
                closest_point_on_triangle(p, corners).distance_squared(p) <= r2
            });
            (!found).then_some(r2)
        });
        found
    }

    /// Walks the tree from `p`, the nearer child first, skipping every box whose squared
    /// distance to `p` exceeds the reach (at first `reach`), and hands each leaf's
    /// triangles to `visit`, which returns the reach from then on, or `None` to stop.
    fn walk(
        &self,
        p: DVec3,
        reach: f64,
        mut visit: impl FnMut(&[([DVec3; 3], u32)]) -> Option<f64>,
    ) {
        let Some(root) = self.nodes.first() else {
            return;
        };
        let mut reach = reach;
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        stack.push((0, box_distance_squared(p, root)));
        while let Some((index, d2)) = stack.pop() {
            if d2 > reach {
                continue;
            }
            let Some(node) = self.nodes.get(index as usize) else {
                continue;
            };
            if node.count > 0 {
                let first = node.first as usize;
                let last = first + node.count as usize;
                match visit(self.triangles.get(first..last).unwrap_or(&[])) {
                    Some(r) => reach = r,
                    None => return,
                }
                continue;
            }
            let (l, r) = (node.first, node.first + 1);
            let distance = |i: u32| {
                self.nodes
                    .get(i as usize)
                    .map_or(f64::INFINITY, |n| box_distance_squared(p, n))
            };
            let (dl, dr) = (distance(l), distance(r));
            // Push the farther child first so that the nearer one is searched first.
            if dl <= dr {
                stack.push((r, dr));
                stack.push((l, dl));
            } else {
                stack.push((l, dl));
                stack.push((r, dr));
            }
        }
    }
}

fn centroid(t: &[DVec3; 3]) -> DVec3 {
    (t[0] + t[1] + t[2]) / 3.0
}

/// Squared distance from `p` to a node's box (0 inside).
fn box_distance_squared(p: DVec3, node: &Node) -> f64 {
    let outside = (node.min - p).max(p - node.max).max(DVec3::ZERO);
    outside.length_squared()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    fn random_triangles(seed: u64, n: usize) -> Vec<([DVec3; 3], u32)> {
        let mut rng = SplitMix64::new(seed);
        (0..n)
            .map(|i| {
                let c = rng.unit_vector() * rng.range_f64(0.0, 5.0);
                let t = [
                    c + rng.unit_vector() * 0.3,
                    c + rng.unit_vector() * 0.3,
                    c + rng.unit_vector() * 0.3,
                ];
                (t, i as u32)
            })
            .collect()
    }

    fn brute_force(triangles: &[([DVec3; 3], u32)], p: DVec3) -> (f64, u32) {
        let mut best = (f64::INFINITY, u32::MAX);
        for &(t, id) in triangles {
            let d2 = closest_point_on_triangle(p, t).distance_squared(p);
            if d2 < best.0 || (d2 == best.0 && id < best.1) {
                best = (d2, id);
            }
        }
        best
    }

    #[test]
    fn answers_exactly_like_brute_force() {
        let triangles = random_triangles(5, 700);
        let bvh = Bvh::build(triangles.clone());
        assert_eq!(bvh.len(), 700);
        let mut rng = SplitMix64::new(6);
        for _ in 0..500 {
            let p = rng.unit_vector() * rng.range_f64(0.0, 8.0);
            let hit = bvh.find_closest(p).unwrap();
            let (d2, id) = brute_force(&triangles, p);
            assert_eq!(hit.distance_squared, d2, "at {p}");
            assert_eq!(hit.id, id, "at {p}");
            assert_eq!(hit.point.distance_squared(p), d2);
        }
    }

    /// `is_within` says what the brute-force distance says, at radii on both sides of it
    /// and at it (within means at most).
    #[test]
    fn is_within_agrees_with_brute_force() {
        let triangles = random_triangles(7, 700);
        let bvh = Bvh::build(triangles.clone());
        let mut rng = SplitMix64::new(8);
        for _ in 0..500 {
            let p = rng.unit_vector() * rng.range_f64(0.0, 8.0);
            let d = brute_force(&triangles, p).0.sqrt();
            assert!(bvh.is_within(p, d * 1.001 + 1e-12), "at {p}");
            assert!(!bvh.is_within(p, d * 0.999 - 1e-12), "at {p}");
            let radius = rng.range_f64(0.0, 3.0);
            assert_eq!(bvh.is_within(p, radius), d <= radius, "at {p}");
        }
        assert!(!Bvh::build(Vec::new()).is_within(DVec3::ZERO, 1.0));
    }

    #[test]
    fn ties_go_to_the_smallest_id_whatever_the_order() {
        // The same triangle four times under different ids, in shuffled order.
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let mut triangles = vec![(t, 9), (t, 3), (t, 7), (t, 5)];
        triangles.extend(random_triangles(1, 40).into_iter().map(|(t, i)| {
            (
                [
                    t[0] + DVec3::splat(20.0),
                    t[1] + DVec3::splat(20.0),
                    t[2] + DVec3::splat(20.0),
                ],
                100 + i,
            )
        }));
        let hit = Bvh::build(triangles.clone()).find_closest(DVec3::new(0.2, 0.2, 1.0));
        assert_eq!(hit.map(|h| h.id), Some(3));
        triangles.reverse();
        let hit = Bvh::build(triangles).find_closest(DVec3::new(0.2, 0.2, 1.0));
        assert_eq!(hit.map(|h| h.id), Some(3));
    }

    #[test]
    fn depth_is_logarithmic_even_with_identical_centroids() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let triangles: Vec<_> = (0..1000).map(|i| (t, i)).collect();
        let bvh = Bvh::build(triangles);
        fn depth(bvh: &Bvh, node: usize) -> usize {
            let n = bvh.nodes[node];
            if n.count > 0 {
                1
            } else {
                1 + depth(bvh, n.first as usize).max(depth(bvh, n.first as usize + 1))
            }
        }
        // 1000 triangles in leaves of <= 4: ⌈log₂(1000/4)⌉ + 1 = 9 levels.
        assert!(depth(&bvh, 0) <= 9, "depth {}", depth(&bvh, 0));
        assert_eq!(bvh.find_closest(DVec3::Z).map(|h| h.id), Some(0));
    }

    #[test]
    fn empty_hierarchy_finds_nothing() {
        let bvh = Bvh::build(Vec::new());
        assert!(bvh.is_empty());
        assert_eq!(bvh.find_closest(DVec3::ZERO), None);
    }
}
