//! Springs by class, and the triangles of the cloth surface.

use std::ops::Range;

/// The kind of a spring: the seed's three classes, with the structural class split along the
/// two weave directions of a fabric.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SpringKind {
    /// Structural, along the warp: between grid neighbours `(r, c)` and `(r + 1, c)`.
    Warp = 0,
    /// Structural, along the weft: between grid neighbours `(r, c)` and `(r, c + 1)`.
    Weft = 1,
    /// Shear: the two diagonals of every grid cell.
    Shear = 2,
    /// Bending: between particles two apart along rows and along columns.
    Bend = 3,
}

impl SpringKind {
    /// All kinds, in storage order.
    pub const ALL: [SpringKind; 4] = [Self::Warp, Self::Weft, Self::Shear, Self::Bend];

    /// The seed's class of this kind (warp and weft are both structural).
    #[must_use]
    pub fn class(self) -> SpringClass {
        match self {
            Self::Warp | Self::Weft => SpringClass::Structural,
            Self::Shear => SpringClass::Shear,
            Self::Bend => SpringClass::Bend,
        }
    }

    /// Lower-case name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Warp => "warp",
            Self::Weft => "weft",
            Self::Shear => "shear",
            Self::Bend => "bend",
        }
    }
}

/// The seed's three spring classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SpringClass {
    /// Grid neighbours (warp and weft).
    Structural = 0,
    /// Cell diagonals.
    Shear = 1,
    /// Two apart.
    Bend = 2,
}

impl SpringClass {
    /// All classes, in order.
    pub const ALL: [SpringClass; 3] = [Self::Structural, Self::Shear, Self::Bend];

    /// Lower-case name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Structural => "structural",
            Self::Shear => "shear",
            Self::Bend => "bend",
        }
    }
}

/// One spring between particles `a` and `b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spring {
    /// First particle.
    pub a: u32,
    /// Second particle.
    pub b: u32,
    /// Rest length, m.
    pub rest_length: f32,
}

/// Area-weighted vertex normals of a triangle mesh, unit length, into `out` (resized). A
/// vertex in no triangle (or only in degenerate ones) gets +Y, so normals are always usable.
///
/// # Panics
/// When a triangle holds an index that is not below `position.len()`.
pub fn vertex_normals(position: &[glam::Vec3], triangles: &[[u32; 3]], out: &mut Vec<glam::Vec3>) {
    out.clear();
    out.resize(position.len(), glam::Vec3::ZERO);
    for &[a, b, c] in triangles {
        let (a, b, c) = (a as usize, b as usize, c as usize);
        // The cross product's length is twice the area: area weighting for free.
        let n = (position[b] - position[a]).cross(position[c] - position[a]);
        out[a] += n;
        out[b] += n;
        out[c] += n;
    }
    for n in out.iter_mut() {
        *n = n.normalize_or(glam::Vec3::Y);
    }
}

/// The springs and triangles of a cloth.
///
/// Springs are stored in one flat `Vec`, grouped by [`SpringKind`] in the order of
/// [`SpringKind::ALL`]; [`Topology::springs_of`] gives one kind's contiguous slice. The order
/// inside a kind is fixed (row-major), which makes every sum over springs deterministic.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Topology {
    springs: Vec<Spring>,
    /// The springs' rest lengths as one array (`rest[j]` of `springs[j]`), for the passes
    /// that read them alone.
    rest: Vec<f32>,
    ranges: [Range<usize>; 4],
    triangles: Vec<[u32; 3]>,
    /// `(rows, cols)` when the springs are exactly those of a regular grid in the builder's
    /// order (set by [`crate::GridBuilder`]): the explicit integrators' grid fast path.
    grid: Option<(usize, usize)>,
}

impl Topology {
    /// Builds a topology from springs grouped per kind (indexed by `SpringKind as usize`) and
    /// triangles (counter-clockwise seen from the side the normal points to).
    #[must_use]
    pub fn new(per_kind: [Vec<Spring>; 4], triangles: Vec<[u32; 3]>) -> Self {
        let mut springs = Vec::with_capacity(per_kind.iter().map(Vec::len).sum());
        let mut ranges: [Range<usize>; 4] = Default::default();
        for (range, group) in ranges.iter_mut().zip(per_kind) {
            let start = springs.len();
            springs.extend(group);
            *range = start..springs.len();
        }
        Self {
            rest: springs.iter().map(|s| s.rest_length).collect(),
            springs,
            ranges,
            triangles,
            grid: None,
        }
    }

    /// Records that the springs are those of a `rows × cols` grid in the builder's order
    /// (see [`Topology::grid`]).
    #[must_use]
    pub(crate) fn with_grid(mut self, rows: usize, cols: usize) -> Self {
        self.grid = Some((rows, cols));
        self
    }

    /// `(rows, cols)` when this is the topology of a regular grid built by
    /// [`crate::GridBuilder`] (springs in its order), which lets the explicit integrators use
    /// their row-sliced fast path; `None` otherwise.
    #[must_use]
    pub fn grid(&self) -> Option<(usize, usize)> {
        self.grid
    }

    /// All springs, grouped by kind.
    #[must_use]
    pub fn springs(&self) -> &[Spring] {
        &self.springs
    }

    /// The rest lengths of [`Topology::springs`], in their order, m.
    #[must_use]
    pub fn rest_lengths(&self) -> &[f32] {
        &self.rest
    }

    /// The springs of one kind.
    #[must_use]
    pub fn springs_of(&self, kind: SpringKind) -> &[Spring] {
        &self.springs[self.ranges[kind as usize].clone()]
    }

    /// Number of springs of one class (warp + weft for [`SpringClass::Structural`]).
    #[must_use]
    pub fn count_of_class(&self, class: SpringClass) -> usize {
        SpringKind::ALL
            .iter()
            .filter(|k| k.class() == class)
            .map(|&k| self.ranges[k as usize].len())
            .sum()
    }

    /// Area-weighted vertex normals of the surface at `position` (see [`vertex_normals`]).
    pub fn vertex_normals(&self, position: &[glam::Vec3], out: &mut Vec<glam::Vec3>) {
        vertex_normals(position, &self.triangles, out);
    }

    /// Triangles of the surface, two per grid cell, counter-clockwise around the cloth's
    /// front normal.
    #[must_use]
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }
}
