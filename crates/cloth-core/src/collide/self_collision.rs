//! Cloth–cloth contact: particles keep a thickness from each other (particle–particle
//! repulsion, as in Ten Minute Physics' self-collision), found with a spatial hash rebuilt every
//! substep.
//!
//! A pair of particles closer than d_min = min(thickness, rest distance) is pushed apart to
//! d_min along the line between them, mass-weighted (a pinned particle does not move). Taking
//! the rest distance into account means neighbours of the flat cloth never repel each other,
//! so no exclusion list is needed. For the force-based integrators the approaching normal
//! relative velocity is also removed (an inelastic contact) and Coulomb-like friction damps the
//! tangential relative velocity; XPBD needs only the positions.
//!
//! Pairs are visited in a fixed order (particles by index; the 27 neighbouring cells in a fixed
//! order; each cell's particles by index, from a counting sort), so results are deterministic.

use glam::{IVec3, Vec3};

use crate::particles::Particles;

/// Self-collision settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelfCollision {
    /// Distance particles keep from each other, m, `> 0`. Default 0.01 m. Use about the grid
    /// spacing: smaller lets coarse cloth pass through itself between particles.
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

/// Separates every pair of particles closer than min(thickness, rest distance). Returns the
/// number of pairs in contact. `h` is the substep (for the velocity update of the force-based
/// integrators); `velocities` says whether to update velocities (false for XPBD).
pub(crate) fn resolve(
    hash: &mut SpatialHash,
    particles: &mut Particles,
    rest: &[Vec3],
    settings: SelfCollision,
    velocities: bool,
) -> u32 {
    let d = settings.thickness;
    hash.build(&particles.position, d);
    let inv = 1.0 / d;
    let mut contacts = 0;
    let n = particles.len();
    for i in 0..n {
        let wi = particles.inv_mass[i];
        let ci = cell_coord(particles.position[i], inv);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let h = hash.hash(ci + IVec3::new(dx, dy, dz)) as usize;
                    let (a, b) = (hash.start[h] as usize, hash.start[h + 1] as usize);
                    for k in a..b {
                        let j = hash.entries[k] as usize;
                        if j <= i {
                            continue;
                        }
                        let wj = particles.inv_mass[j];
                        let w = wi + wj;
                        if w == 0.0 {
                            continue;
                        }
                        let delta = particles.position[i] - particles.position[j];
                        let dist_sq = delta.length_squared();
                        let d_min = d.min(rest[i].distance(rest[j]));
                        if dist_sq >= d_min * d_min || dist_sq == 0.0 {
                            continue;
                        }
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
                                // The relative velocity changes by −dv: its approaching normal
                                // part is removed and its tangential part damped; shared by mass.
                                let dv = vn * nrm + damp * vt;
                                particles.velocity[i] -= (wi / w) * dv;
                                particles.velocity[j] += (wj / w) * dv;
                            }
                        }
                    }
                }
            }
        }
    }
    contacts
}
