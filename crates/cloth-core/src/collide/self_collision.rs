//! Cloth–cloth contact: particles keep a thickness from each other (particle–particle
//! repulsion, as in Ten Minute Physics' self-collision), found with a spatial hash and a cached
//! list of candidate pairs that is rebuilt only when particles have moved far enough to need
//! it (see `SelfCollisionScratch`).
//!
//! A pair of particles closer than d_min = min(thickness, rest distance) is pushed apart to
//! d_min along the line between them, mass-weighted (a pinned particle does not move). Taking
//! the rest distance into account means neighbours of the flat cloth never repel each other,
//! so no exclusion list is needed. For the force-based integrators the approaching normal
//! relative velocity is also removed (an inelastic contact) and Coulomb-like friction damps the
//! tangential relative velocity; XPBD needs only the positions.
//!
//! Pairs are visited in a fixed order (by the first particle's index, then the second's), so
//! results are deterministic.

use glam::{IVec3, Vec3};

use crate::particles::Particles;

/// Self-collision settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelfCollision {
    /// Distance particles keep from each other, m, `> 0` and at most
    /// [`crate::MAX_SELF_COLLISION_SPACINGS`] (16) grid spacings. Default 0.01 m. Use
    /// about the grid spacing: smaller lets coarse cloth pass through itself between
    /// particles.
    pub thickness: f32,
    /// Friction between touching layers, `>= 0`: the tangential relative speed of a contact
    /// drops by at most this times its normal speed change. Default 0.3.
    pub friction: f32,
}

impl Default for SelfCollision {
    fn default() -> Self {
        Self {
            thickness: 0.01,
            friction: 0.3,
        }
    }
}

/// A spatial hash over particle positions (reused scratch: no allocation after the first
/// build of a given particle count).
#[derive(Debug, Clone, Default)]
pub(crate) struct SpatialHash {
    /// `start[c]..start[c + 1]` indexes `entries` for hash cell c.
    start: Vec<u32>,
    /// Particle indices sorted by hash cell, ascending within a cell.
    entries: Vec<u32>,
    /// Hash cell of each particle.
    cell_of: Vec<u32>,
    /// Scatter cursor per cell (scratch of `build`).
    fill: Vec<u32>,
}

fn cell_coord(p: Vec3, inv: f32) -> IVec3 {
    (p * inv).floor().as_ivec3()
}

impl SpatialHash {
    fn hash(&self, c: IVec3) -> u32 {
        let h = (c.x.wrapping_mul(92_837_111))
            ^ (c.y.wrapping_mul(689_287_499))
            ^ (c.z.wrapping_mul(283_923_481));
        (h.unsigned_abs()) % (self.start.len() as u32 - 1)
    }

    /// Rebuilds the hash for `positions` with cells of `spacing` metres.
    pub fn build(&mut self, positions: &[Vec3], spacing: f32) {
        let n = positions.len();
        let table = 2 * n + 1;
        self.start.clear();
        self.start.resize(table + 1, 0);
        self.cell_of.clear();
        self.entries.clear();
        self.entries.resize(n, 0);
        let inv = 1.0 / spacing;
        for &p in positions {
            let h = self.hash(cell_coord(p, inv));
            self.cell_of.push(h);
            self.start[h as usize] += 1;
        }
        // Exclusive prefix sums, then a stable scatter by particle index.
        let mut sum = 0;
        for s in &mut self.start {
            let count = *s;
            *s = sum;
            sum += count;
        }
        self.fill.clone_from(&self.start);
        for (i, &h) in self.cell_of.iter().enumerate() {
            let slot = &mut self.fill[h as usize];
            self.entries[*slot as usize] = i as u32;
            *slot += 1;
        }
    }
}

/// Self-collision scratch: the spatial hash and a cached list of candidate pairs.
///
/// Rebuilding the hash and querying 27 cells for every particle every substep is what makes
/// naive self-collision expensive. Instead, candidate pairs closer than `R = thickness +
/// 2·margin` are collected into a list (with their d_min), and each substep only visits that
/// list. The list stays valid while no particle has moved more than `margin` from where it
/// was when the list was built: a pair not in the list was at least R apart then, so it is
/// still at least R − 2·margin = thickness apart, too far to touch. When some particle moved
/// further, the list is rebuilt. So the cache changes the cost, never the result.
#[derive(Debug, Clone, Default)]
pub(crate) struct SelfCollisionScratch {
    hash: SpatialHash,
    /// Candidate pairs `(i, j, d_min)` with i < j, sorted by (i, j).
    pairs: Vec<(u32, u32, f32)>,
    /// Positions when `pairs` was built.
    anchor: Vec<Vec3>,
    /// Margin the list was built with, m (0: no list yet).
    margin: f32,
    /// Number of list rebuilds (for tests and diagnostics).
    pub rebuilds: u64,
}

impl SelfCollisionScratch {
    /// Makes sure the pair list covers every pair that can be closer than `thickness` now.
    fn refresh(&mut self, particles: &Particles, rest: &[Vec3], thickness: f32) {
        let margin = 0.5 * thickness;
        let n = particles.len();
        let valid = self.margin == margin && self.anchor.len() == n && {
            let m2 = margin * margin;
            particles
                .position
                .iter()
                .zip(&self.anchor)
                .all(|(p, a)| p.distance_squared(*a) <= m2)
        };
        if valid {
            return;
        }
        self.rebuilds += 1;
        self.margin = margin;
        self.anchor.clone_from(&particles.position);
        let radius = thickness + 2.0 * margin;
        self.hash.build(&particles.position, radius);
        self.pairs.clear();
        // Room for 12 candidate pairs per particle (a flat sheet has about 6 within R, two
        // layers in contact about 12), so that a step does not allocate after the first
        // unless the cloth is heaped denser than that.
        self.pairs.reserve(12 * n);
        collect_pairs(&self.hash, particles, radius, &mut self.pairs, |i, j| {
            thickness.min(rest[i].distance(rest[j]))
        });
    }
}

/// Appends to `pairs`, for each particle i in index order, every particle j > i closer than
/// `radius` to it (pairs of two pinned particles left out), in ascending order of j, with
/// `value(i, j)`. `hash` must have been built from `particles.position` with cells of
/// `radius`.
fn collect_pairs<T>(
    hash: &SpatialHash,
    particles: &Particles,
    radius: f32,
    pairs: &mut Vec<(u32, u32, T)>,
    value: impl Fn(usize, usize) -> T,
) {
    let inv = 1.0 / radius;
    let r2 = radius * radius;
    for (i, &xi) in particles.position.iter().enumerate() {
        let first = pairs.len();
        let ci = cell_coord(xi, inv);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    // Wrapping: a cell coordinate saturates at i32::MAX for a particle far
                    // out or a tiny thickness, and its neighbour then wraps (the hash wraps
                    // anyway; candidates are checked by distance below).
                    let h = hash.hash(ci.wrapping_add(IVec3::new(dx, dy, dz))) as usize;
                    let (a, b) = (hash.start[h] as usize, hash.start[h + 1] as usize);
                    for &j in &hash.entries[a..b] {
                        let ju = j as usize;
                        if ju <= i
                            || particles.inv_mass[i] + particles.inv_mass[ju] == 0.0
                            || xi.distance_squared(particles.position[ju]) >= r2
                        {
                            continue;
                        }
                        pairs.push((i as u32, j, value(i, ju)));
                    }
                }
            }
        }
        // Canonical order, and no duplicates from cells sharing a hash bucket.
        pairs[first..].sort_unstable_by_key(|p| p.1);
        let mut w = first;
        for r in first..pairs.len() {
            if w == first || pairs[w - 1].1 != pairs[r].1 {
                pairs.swap(w, r);
                w += 1;
            }
        }
        pairs.truncate(w);
    }
}

/// The cloth's layer contacts of the current state, appended to `out` as contacts of both
/// particles: every pair closer than `reach` that was at least `reach` apart in the rest
/// shape (layers touching, not neighbours), pairs of two pinned particles left out. Found
/// with a hash built for the call (not the solver's cached pair list, which covers only the
/// pairs within the thickness, and only as of the last step).
pub(crate) fn layer_contacts(
    particles: &Particles,
    rest: &[Vec3],
    reach: f32,
    out: &mut Vec<crate::sim::Contact>,
) {
    use crate::sim::{Contact, ContactWith};
    let mut hash = SpatialHash::default();
    hash.build(&particles.position, reach);
    let mut pairs = Vec::new();
    collect_pairs(&hash, particles, reach, &mut pairs, |_, _| ());
    for (i, j, ()) in pairs {
        let (iu, ju) = (i as usize, j as usize);
        let d = particles.position[iu] - particles.position[ju];
        let len = d.length();
        if rest[iu].distance(rest[ju]) < reach || len == 0.0 {
            continue;
        }
        let n = d / len;
        out.push(Contact {
            particle: i,
            normal: n,
            with: ContactWith::Cloth(j),
        });
        out.push(Contact {
            particle: j,
            normal: -n,
            with: ContactWith::Cloth(i),
        });
    }
}

/// Separates every pair of particles closer than min(thickness, rest distance). Returns the
/// number of pairs in contact. `velocities` says whether to update velocities (the
/// force-based integrators; false for XPBD).
pub(crate) fn resolve(
    scratch: &mut SelfCollisionScratch,
    particles: &mut Particles,
    rest: &[Vec3],
    settings: SelfCollision,
    velocities: bool,
) -> u32 {
    scratch.refresh(particles, rest, settings.thickness);
    let mut contacts = 0;
    for &(i, j, d_min) in &scratch.pairs {
        let (i, j) = (i as usize, j as usize);
        let delta = particles.position[i] - particles.position[j];
        let dist_sq = delta.length_squared();
        if dist_sq >= d_min * d_min || dist_sq == 0.0 {
            continue;
        }
        let (wi, wj) = (particles.inv_mass[i], particles.inv_mass[j]);
        let w = wi + wj;
        contacts += 1;
        let dist = dist_sq.sqrt();
        let nrm = delta / dist;
        let push = (d_min - dist) / w;
        particles.position[i] += (wi * push) * nrm;
        particles.position[j] -= (wj * push) * nrm;
        if velocities {
            let v_rel = particles.velocity[i] - particles.velocity[j];
            let vn = v_rel.dot(nrm);
            if vn < 0.0 {
                let vt = v_rel - vn * nrm;
                let vt_len = vt.length();
                let damp = if vt_len > 0.0 {
                    (settings.friction * -vn / vt_len).min(1.0)
                } else {
                    0.0
                };
                // The relative velocity changes by −dv: its approaching normal part is
                // removed and its tangential part damped; shared by mass.
                let dv = vn * nrm + damp * vt;
                particles.velocity[i] -= (wi / w) * dv;
                particles.velocity[j] += (wj / w) * dv;
            }
        }
    }
    contacts
}
