//! Self-contact diagnostics of the cloth mesh: an exact count of intersecting triangle pairs
//! and the smallest distance from a particle to a triangle that is not its neighbour.
//!
//! * **Intersections.** Two triangles that share no vertex intersect (as closed sets) exactly
//!   when an edge of one meets the other. Each edge–triangle test uses only the signs of
//!   Shewchuk's adaptive-precision `orient3d` (and `orient2d` when the edge lies in the
//!   triangle's plane), computed exactly from the f32 positions by the `robust` crate, so
//!   the count has no rounding error: a pair is counted if and only if the triangles of the
//!   stored positions intersect. Triangles that share a vertex are not tested (they always
//!   touch there).
//! * **Proximity.** For every particle, the closest point of every triangle within a search
//!   range that neither contains the particle nor was within that range of it in the rest
//!   shape (the same neighbour rule as the particle–particle self-collision).
//!
//! Broad phase: a hashed uniform grid whose cells are at least as large as any triangle's
//! bounding box, so a triangle covers at most 2×2×2 cells; buckets are filled by a counting
//! sort in triangle order and candidates deduplicated with a stamp per triangle, so the result
//! is deterministic and nothing is allocated after the first call for a given mesh size.

use glam::Vec3;
use robust::{Coord, Coord3D, orient2d, orient3d};

use super::mesh::closest_point_on_triangle;
use crate::error::{ClothError, Result, check};

/// What [`SelfContactCheck::run`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelfContact {
    /// Pairs of triangles (sharing no vertex) that intersect.
    pub self_intersections: u32,
    /// Smallest distance from a particle to a non-neighbour triangle, m, looking only within
    /// the search range (`f32::INFINITY` when nothing is that close).
    pub min_distance: f32,
}

/// Reusable scratch for the self-contact diagnostics.
#[derive(Debug, Default, Clone)]
pub struct SelfContactCheck {
    lo: Vec<Vec3>,
    hi: Vec<Vec3>,
    bucket_start: Vec<u32>,
    entries: Vec<u32>,
    stamp: Vec<u32>,
}

#[inline]
fn cell_of(p: Vec3, inv: f32) -> [i32; 3] {
    [
        (p.x * inv).floor() as i32,
        (p.y * inv).floor() as i32,
        (p.z * inv).floor() as i32,
    ]
}

#[inline]
fn bucket(c: [i32; 3], mask: usize) -> usize {
    let h = (c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791);
    h as usize & mask
}

impl SelfContactCheck {
    /// Counts intersecting triangle pairs of the mesh at `position` and the smallest
    /// particle–triangle distance within `range` (m) over non-neighbour pairs (neighbours:
    /// the particle is a corner of the triangle, or the triangle was closer than `range` in
    /// the `rest` shape).
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] when `range` is not a finite length > 0, when `rest`
    /// and `position` differ in length or hold a non-finite position, or when a triangle
    /// names a particle that does not exist.
    pub fn run(
        &mut self,
        position: &[Vec3],
        rest: &[Vec3],
        triangles: &[[u32; 3]],
        range: f32,
    ) -> Result<SelfContact> {
        check::positive("self_contact.range", range)?;
        if rest.len() != position.len() {
            return Err(ClothError::invalid(
                "self_contact.rest",
                rest.len(),
                format!("{} positions (one per particle)", position.len()),
            ));
        }
        // Checked once here, so the pair tests below need not check every corner again.
        for (name, points) in [
            ("self_contact.position", position),
            ("self_contact.rest", rest),
        ] {
            if let Some(i) = points.iter().position(|p| !p.is_finite()) {
                return Err(ClothError::invalid(
                    format!("{name}[{i}]"),
                    points[i],
                    "finite coordinates",
                ));
            }
        }
        if let Some(t) = triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= position.len()))
        {
            return Err(ClothError::invalid(
                "self_contact.triangles",
                t,
                format!(
                    "particle indices in 0 ..= {}",
                    position.len().saturating_sub(1)
                ),
            ));
        }
        Ok(self.run_checked(position, rest, triangles, range))
    }

    /// [`run`](Self::run) on arguments already checked.
    fn run_checked(
        &mut self,
        position: &[Vec3],
        rest: &[Vec3],
        triangles: &[[u32; 3]],
        range: f32,
    ) -> SelfContact {
        let mut result = SelfContact {
            self_intersections: 0,
            min_distance: f32::INFINITY,
        };
        let nt = triangles.len();
        if nt == 0 {
            return result;
        }
        // Triangle boxes and the cell size.
        self.lo.clear();
        self.hi.clear();
        let mut cell = range.max(1e-6);
        for t in triangles {
            let [a, b, c] = t.map(|i| position[i as usize]);
            let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
            cell = cell.max((hi - lo).max_element());
            self.lo.push(lo);
            self.hi.push(hi);
        }
        let inv = 1.0 / cell;
        let size = (2 * nt).next_power_of_two();
        let mask = size - 1;
        // Counting sort of (cell, triangle) into buckets.
        self.bucket_start.clear();
        self.bucket_start.resize(size + 1, 0);
        let cells = |lo: Vec3, hi: Vec3| {
            let (a, b) = (cell_of(lo, inv), cell_of(hi, inv));
            (a[0]..=b[0]).flat_map(move |x| {
                (a[1]..=b[1]).flat_map(move |y| (a[2]..=b[2]).map(move |z| [x, y, z]))
            })
        };
        for t in 0..nt {
            for c in cells(self.lo[t], self.hi[t]) {
                self.bucket_start[bucket(c, mask) + 1] += 1;
            }
        }
        for i in 0..size {
            self.bucket_start[i + 1] += self.bucket_start[i];
        }
        self.entries.clear();
        self.entries.resize(self.bucket_start[size] as usize, 0);
        // `stamp` doubles as the fill cursor per bucket here.
        self.stamp.clear();
        self.stamp.extend_from_slice(&self.bucket_start[..size]);
        for t in 0..nt {
            for c in cells(self.lo[t], self.hi[t]) {
                let b = bucket(c, mask);
                self.entries[self.stamp[b] as usize] = t as u32;
                self.stamp[b] += 1;
            }
        }
        self.stamp.clear();
        self.stamp.resize(nt.max(position.len()), u32::MAX);

        // Triangle pairs.
        for t in 0..nt {
            let tri = triangles[t];
            for c in cells(self.lo[t], self.hi[t]) {
                let b = bucket(c, mask);
                let range_b = self.bucket_start[b] as usize..self.bucket_start[b + 1] as usize;
                for &u in &self.entries[range_b] {
                    let u = u as usize;
                    if u <= t || self.stamp[u] == t as u32 {
                        continue;
                    }
                    self.stamp[u] = t as u32;
                    if self.lo[t].cmpgt(self.hi[u]).any() || self.lo[u].cmpgt(self.hi[t]).any() {
                        continue;
                    }
                    let other = triangles[u];
                    if tri.iter().any(|i| other.contains(i)) {
                        continue;
                    }
                    let p = tri.map(|i| position[i as usize]);
                    let q = other.map(|i| position[i as usize]);
                    if finite_triangles_intersect(p, q) {
                        result.self_intersections += 1;
                    }
                }
            }
        }

        // Particle–triangle proximity.
        self.stamp.fill(u32::MAX);
        let r = Vec3::splat(range);
        for (i, &x) in position.iter().enumerate() {
            for c in cells(x - r, x + r) {
                let b = bucket(c, mask);
                let range_b = self.bucket_start[b] as usize..self.bucket_start[b + 1] as usize;
                for &u in &self.entries[range_b] {
                    let u = u as usize;
                    if self.stamp[u] == i as u32 {
                        continue;
                    }
                    self.stamp[u] = i as u32;
                    let tri = triangles[u];
                    if tri.contains(&(i as u32))
                        || (x - r).cmpgt(self.hi[u]).any()
                        || self.lo[u].cmpgt(x + r).any()
                    {
                        continue;
                    }
                    let [a, b, c] = tri.map(|k| position[k as usize]);
                    let d = x.distance(closest_point_on_triangle(x, a, b, c));
                    if d >= range || d >= result.min_distance {
                        continue;
                    }
                    let [ra, rb, rc] = tri.map(|k| rest[k as usize]);
                    let rest_d = rest[i].distance(closest_point_on_triangle(rest[i], ra, rb, rc));
                    if rest_d < range {
                        continue;
                    }
                    result.min_distance = d;
                }
            }
        }
        result
    }
}

#[inline]
fn c3(p: Vec3) -> Coord3D<f32> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

#[inline]
fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

#[inline]
fn o3(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> i8 {
    sign(orient3d(c3(a), c3(b), c3(c), c3(d)))
}

/// Whether closed triangles `p` and `q` (in general position or not) intersect. Exact.
/// A triangle with a non-finite corner has no position, so it meets nothing (`false`).
#[must_use]
pub fn triangles_intersect(p: [Vec3; 3], q: [Vec3; 3]) -> bool {
    p.iter().chain(&q).all(|v| v.is_finite()) && finite_triangles_intersect(p, q)
}

/// [`triangles_intersect`] for corners known to be finite.
fn finite_triangles_intersect(p: [Vec3; 3], q: [Vec3; 3]) -> bool {
    (0..3).any(|k| segment_meets_triangle(p[k], p[(k + 1) % 3], q))
        || (0..3).any(|k| segment_meets_triangle(q[k], q[(k + 1) % 3], p))
}

/// Whether the closed segment `s0 s1` meets the closed triangle `t`. Exact.
fn segment_meets_triangle(s0: Vec3, s1: Vec3, t: [Vec3; 3]) -> bool {
    let [a, b, c] = t;
    let d0 = o3(a, b, c, s0);
    let d1 = o3(a, b, c, s1);
    if d0 * d1 > 0 {
        return false;
    }
    if d0 == 0 && d1 == 0 {
        return coplanar_segment_meets_triangle(s0, s1, t);
    }
    // The segment crosses (or touches) the plane at one point, on the line s0 s1: it is in
    // the triangle iff the line passes on the same side of all three edges.
    let e0 = o3(s0, s1, a, b);
    let e1 = o3(s0, s1, b, c);
    let e2 = o3(s0, s1, c, a);
    (e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0)
}

/// The segment and the triangle lie in one plane: test in the coordinate plane where the
/// triangle's projection has the largest area (dropping a coordinate is exact).
fn coplanar_segment_meets_triangle(s0: Vec3, s1: Vec3, t: [Vec3; 3]) -> bool {
    let n = (t[1] - t[0])
        .as_dvec3()
        .cross((t[2] - t[0]).as_dvec3())
        .abs();
    let drop = if n.x >= n.y && n.x >= n.z {
        0
    } else if n.y >= n.z {
        1
    } else {
        2
    };
    let proj = |p: Vec3| match drop {
        0 => Coord { x: p.y, y: p.z },
        1 => Coord { x: p.z, y: p.x },
        _ => Coord { x: p.x, y: p.y },
    };
    let (s0, s1) = (proj(s0), proj(s1));
    let [a, b, c] = t.map(proj);
    let o = |p: Coord<f32>, q: Coord<f32>, r: Coord<f32>| sign(orient2d(p, q, r));
    let orientation = o(a, b, c);
    if orientation == 0 {
        return false; // degenerate projection (a zero-area triangle)
    }
    let inside = |p: Coord<f32>| {
        o(a, b, p) * orientation >= 0
            && o(b, c, p) * orientation >= 0
            && o(c, a, p) * orientation >= 0
    };
    if inside(s0) || inside(s1) {
        return true;
    }
    [(a, b), (b, c), (c, a)]
        .iter()
        .any(|&(p, q)| segments_meet_2d(s0, s1, p, q, o))
}

fn segments_meet_2d(
    a: Coord<f32>,
    b: Coord<f32>,
    c: Coord<f32>,
    d: Coord<f32>,
    o: impl Fn(Coord<f32>, Coord<f32>, Coord<f32>) -> i8,
) -> bool {
    let (d1, d2) = (o(a, b, c), o(a, b, d));
    let (d3, d4) = (o(c, d, a), o(c, d, b));
    if d1 * d2 < 0 && d3 * d4 < 0 {
        return true;
    }
    let on = |p: Coord<f32>, q: Coord<f32>, r: Coord<f32>| {
        r.x >= p.x.min(q.x) && r.x <= p.x.max(q.x) && r.y >= p.y.min(q.y) && r.y <= p.y.max(q.y)
    };
    (d1 == 0 && on(a, b, c))
        || (d2 == 0 && on(a, b, d))
        || (d3 == 0 && on(c, d, a))
        || (d4 == 0 && on(c, d, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> [Vec3; 3] {
        [Vec3::from(a), Vec3::from(b), Vec3::from(c)]
    }

    #[test]
    fn exact_cases() {
        let base = t([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        // A corner that is not a position meets nothing (it used to "intersect").
        assert!(!triangles_intersect([Vec3::NAN; 3], base));
        assert!(!triangles_intersect(
            base,
            t([0.2, 0.2, f32::INFINITY], [0.2, 0.2, 1.0], [2.0, 2.0, 0.5])
        ));
        // Piercing.
        assert!(triangles_intersect(
            base,
            t([0.2, 0.2, -1.0], [0.2, 0.2, 1.0], [2.0, 2.0, 0.5])
        ));
        // Above, no contact.
        assert!(!triangles_intersect(
            base,
            t([0.2, 0.2, 0.1], [0.3, 0.2, 1.0], [0.2, 0.4, 0.5])
        ));
        // Touching at a point (closed sets).
        assert!(triangles_intersect(
            base,
            t([0.25, 0.25, 0.0], [0.3, 0.2, 1.0], [0.2, 0.4, 0.5])
        ));
        // Coplanar, disjoint and overlapping; one inside the other.
        assert!(!triangles_intersect(
            base,
            t([1.0, 1.0, 0.0], [2.0, 1.0, 0.0], [1.0, 2.0, 0.0])
        ));
        assert!(triangles_intersect(
            base,
            t([0.4, 0.4, 0.0], [2.0, 0.1, 0.0], [0.1, 2.0, 0.0])
        ));
        assert!(triangles_intersect(
            base,
            t([0.1, 0.1, 0.0], [0.2, 0.1, 0.0], [0.1, 0.2, 0.0])
        ));
        // Just above by one ulp at z = 1: exact predicates see the gap.
        let eps = f32::EPSILON;
        assert!(!triangles_intersect(
            t([0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]),
            t([0.2, 0.2, 1.0 + eps], [0.3, 0.2, 2.0], [0.2, 0.4, 2.0])
        ));
    }
}
