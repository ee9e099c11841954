//! The grid builder: rows × cols particles and their springs.

use glam::{Quat, Vec3};

use crate::error::{ClothError, Result, check};
use crate::particles::Particles;
use crate::topology::{Spring, SpringKind, Topology};

/// Largest number of rows or columns a grid may have.
pub const MAX_GRID_SIDE: usize = 8192;

/// Largest width or height a grid may have, m (10 km). Far beyond any cloth, and far below
/// where `f32` squared lengths overflow (about 1.8·10¹⁹ m).
pub const MAX_CLOTH_EXTENT: f32 = 1.0e4;

/// How many representable f32 steps (at the cloth's largest coordinate) a grid spacing must
/// span: 64, so a spring's length is known to about 1/64 of its rest length at worst (a 1 cm
/// spacing may lie up to 1.3 km from the world origin).
pub const RESOLVED_ULPS: f32 = 64.0;

/// Largest spacing between `points` particles in a line (≥ 2) that keeps the line within
/// [`MAX_CLOTH_EXTENT`], m.
pub(crate) fn max_spacing(points: usize) -> f32 {
    MAX_CLOTH_EXTENT / (points - 1) as f32
}

/// Which plane the cloth lies in before the builder's rotation is applied.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Orientation {
    /// In the XZ plane: columns along +X, rows along +Z, front normal +Y. The default.
    #[default]
    Horizontal,
    /// In the XY plane: columns along +X, rows downward along −Y (row 0 is the top edge),
    /// front normal +Z.
    Vertical,
}

/// How particle masses are given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mass {
    /// Every particle has this mass, kg.
    PerParticle(f32),
    /// An areal density, kg/m², spread over the grid: each particle gets the mass of the area
    /// nearest to it (a full cell inside, half a cell on an edge, a quarter at a corner), so
    /// the total is density × width × height.
    ArealDensity(f32),
}

impl Default for Mass {
    /// 0.2 kg/m², a light cotton.
    fn default() -> Self {
        Self::ArealDensity(0.2)
    }
}

/// A corner of the grid. Row 0 is the "top" edge, column 0 the "left" one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Corner {
    /// Row 0, column 0.
    TopLeft,
    /// Row 0, last column.
    TopRight,
    /// Last row, column 0.
    BottomLeft,
    /// Last row, last column.
    BottomRight,
}

/// An edge of the grid. Row 0 is the "top" edge, column 0 the "left" one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Edge {
    /// Row 0.
    Top,
    /// The last row.
    Bottom,
    /// Column 0.
    Left,
    /// The last column.
    Right,
}

type PinPredicate = Box<dyn Fn(usize, usize, Vec3) -> bool>;

/// What the builder pins.
enum PinSpec {
    Corners(Vec<Corner>),
    Edge(Edge),
    Indices(Vec<u32>),
    Predicate(PinPredicate),
}

/// A cloth: its particles, its springs and triangles, and the grid they came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Cloth {
    /// Particle state.
    pub particles: Particles,
    /// Springs and triangles.
    pub topology: Topology,
    /// Rows of the grid (particles along the warp).
    pub rows: usize,
    /// Columns of the grid (particles along the weft).
    pub cols: usize,
}

impl Cloth {
    /// Checks that the parts fit together, for a cloth not made by [`GridBuilder`] or
    /// changed since (its fields are public); [`crate::Simulation::new`] calls it.
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] naming the first field found wrong:
    /// - `cloth.particles.*`: arrays of different lengths, no particle or more than
    ///   `u32::MAX`, a non-finite position or velocity, a mass that is not finite and `> 0`
    ///   with a finite inverse, an inverse mass other than 0 (pinned) or 1/mass;
    /// - `cloth.rows`, `cloth.cols`: `rows × cols` other than the particle count, or another
    ///   size than the grid the topology was built for;
    /// - `cloth.topology.springs[j]`: an end that is not a particle, both ends the same
    ///   particle, a rest length that is not finite and `> 0`;
    /// - `cloth.topology.triangles[t]`: a corner that is not a particle.
    pub fn validate(&self) -> Result<()> {
        let p = &self.particles;
        let n = p.position.len();
        for (name, len) in [
            ("cloth.particles.velocity", p.velocity.len()),
            ("cloth.particles.mass", p.mass.len()),
            ("cloth.particles.inv_mass", p.inv_mass.len()),
        ] {
            if len != n {
                return Err(ClothError::invalid(
                    name,
                    format_args!("{len} entries"),
                    format!("{n} entries (one per position)"),
                ));
            }
        }
        if !(1..=u32::MAX as usize).contains(&n) {
            return Err(ClothError::invalid(
                "cloth.particles.position",
                format_args!("{n} entries"),
                format!("1 ..= {} particles", u32::MAX),
            ));
        }
        if self.rows.checked_mul(self.cols) != Some(n) {
            return Err(ClothError::invalid(
                "cloth.rows × cloth.cols",
                format_args!("{} × {}", self.rows, self.cols),
                format!("{n} (the particle count)"),
            ));
        }
        if let Some((rows, cols)) = self.topology.grid()
            && (rows, cols) != (self.rows, self.cols)
        {
            return Err(ClothError::invalid(
                "cloth.rows × cloth.cols",
                format_args!("{} × {}", self.rows, self.cols),
                format!("{rows} × {cols} (the grid the topology was built for)"),
            ));
        }
        for (name, values) in [
            ("cloth.particles.position", &p.position),
            ("cloth.particles.velocity", &p.velocity),
        ] {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(ClothError::invalid(
                    format!("{name}[{i}]"),
                    values[i],
                    "finite components",
                ));
            }
        }
        for (i, (&m, &w)) in p.mass.iter().zip(&p.inv_mass).enumerate() {
            crate::particles::check_mass(m).map_err(|allowed| {
                ClothError::invalid(format!("cloth.particles.mass[{i}]"), m, allowed)
            })?;
            if w != 0.0 && w != 1.0 / m {
                return Err(ClothError::invalid(
                    format!("cloth.particles.inv_mass[{i}]"),
                    w,
                    format!("0 (pinned) or {} (1/mass)", 1.0 / m),
                ));
            }
        }
        for (j, s) in self.topology.springs().iter().enumerate() {
            if s.a as usize >= n || s.b as usize >= n || s.a == s.b {
                return Err(ClothError::invalid(
                    format!("cloth.topology.springs[{j}]"),
                    format_args!("{} – {}", s.a, s.b),
                    format!("two different particles 0 ..= {}", n - 1),
                ));
            }
            if !(s.rest_length.is_finite() && s.rest_length > 0.0) {
                return Err(ClothError::invalid(
                    format!("cloth.topology.springs[{j}].rest_length"),
                    s.rest_length,
                    "a finite length > 0 m",
                ));
            }
        }
        if let Some(t) = self
            .topology
            .triangles()
            .iter()
            .position(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(ClothError::invalid(
                format!("cloth.topology.triangles[{t}]"),
                self.topology.triangles()[t],
                format!("three particles 0 ..= {}", n - 1),
            ));
        }
        Ok(())
    }

    /// Index of the particle at `(row, col)`: `row * cols + col` (not checked against the
    /// grid: a `col` past `cols` is another row's particle).
    ///
    /// # Panics
    /// When `row * cols + col` overflows `usize`.
    #[must_use]
    pub fn index(&self, row: usize, col: usize) -> usize {
        row.checked_mul(self.cols)
            .and_then(|i| i.checked_add(col))
            .expect("Cloth::index: row * cols + col overflows usize")
    }
}

/// Builds a rectangular cloth of `rows × cols` particles.
///
/// The grid is centred on [`origin`](Self::origin): local coordinates run from −width/2 to
/// +width/2 along the columns and −height/2 to +height/2 along the rows, in the plane given by
/// [`orientation`](Self::orientation), then [`rotation`](Self::rotation) turns them about the
/// origin. Particle `(row, col)` has index `row * cols + col`.
///
/// Springs (rest lengths from the built shape, so a cloth starts unstretched):
/// structural warp `(r, c)–(r+1, c)`, structural weft `(r, c)–(r, c+1)`, shear on both cell
/// diagonals, bend `(r, c)–(r+2, c)` and `(r, c)–(r, c+2)`.
///
/// ```
/// use cloth_core::{Edge, GridBuilder, Orientation};
/// let cloth = GridBuilder::new(10, 20)
///     .size(2.0, 1.0)
///     .orientation(Orientation::Vertical)
///     .pin_edge(Edge::Top)
///     .build()?;
/// assert_eq!(cloth.particles.len(), 200);
/// assert!(cloth.particles.is_pinned(5));
/// # Ok::<(), cloth_core::ClothError>(())
/// ```
#[must_use]
pub struct GridBuilder {
    rows: usize,
    cols: usize,
    extent: Extent,
    orientation: Orientation,
    origin: Vec3,
    rotation: Quat,
    velocity: Vec3,
    mass: Mass,
    pins: Vec<PinSpec>,
}

#[derive(Debug, Clone, Copy)]
enum Extent {
    Size { width: f32, height: f32 },
    Spacing { along_cols: f32, along_rows: f32 },
}

impl std::fmt::Debug for GridBuilder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GridBuilder")
            .field("rows", &self.rows)
            .field("cols", &self.cols)
            .field("extent", &self.extent)
            .field("orientation", &self.orientation)
            .field("origin", &self.origin)
            .field("rotation", &self.rotation)
            .field("velocity", &self.velocity)
            .field("mass", &self.mass)
            .field("pins", &self.pins.len())
            .finish()
    }
}

impl GridBuilder {
    /// A grid of `rows × cols` particles, 1 m × 1 m, horizontal, centred on the origin, at
    /// rest, with [`Mass::default`], nothing pinned.
    pub fn new(rows: usize, cols: usize) -> Self {
        Self {
            rows,
            cols,
            extent: Extent::Size {
                width: 1.0,
                height: 1.0,
            },
            orientation: Orientation::Horizontal,
            origin: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            velocity: Vec3::ZERO,
            mass: Mass::default(),
            pins: Vec::new(),
        }
    }

    /// Overall size: `width` along the columns and `height` along the rows, m, each in
    /// `(0, MAX_CLOTH_EXTENT]` ([`MAX_CLOTH_EXTENT`], 10 km).
    pub fn size(mut self, width: f32, height: f32) -> Self {
        self.extent = Extent::Size { width, height };
        self
    }

    /// Distance between neighbouring particles instead of an overall size: `along_cols`
    /// between columns, `along_rows` between rows, m, each > 0 with the whole cloth at most
    /// [`MAX_CLOTH_EXTENT`] (10 km) wide and high.
    pub fn spacing(mut self, along_cols: f32, along_rows: f32) -> Self {
        self.extent = Extent::Spacing {
            along_cols,
            along_rows,
        };
        self
    }

    /// The plane the cloth lies in before rotation.
    pub fn orientation(mut self, orientation: Orientation) -> Self {
        self.orientation = orientation;
        self
    }

    /// World position of the grid's centre, m.
    pub fn origin(mut self, origin: Vec3) -> Self {
        self.origin = origin;
        self
    }

    /// Rotation about the origin, applied after the orientation.
    pub fn rotation(mut self, rotation: Quat) -> Self {
        self.rotation = rotation;
        self
    }

    /// Initial velocity of every particle (pinned ones stay at rest), m/s.
    pub fn velocity(mut self, velocity: Vec3) -> Self {
        self.velocity = velocity;
        self
    }

    /// How masses are given.
    pub fn mass(mut self, mass: Mass) -> Self {
        self.mass = mass;
        self
    }

    /// Pins one corner (may be called repeatedly).
    pub fn pin_corner(mut self, corner: Corner) -> Self {
        self.pins.push(PinSpec::Corners(vec![corner]));
        self
    }

    /// Pins all four corners.
    pub fn pin_corners(mut self) -> Self {
        self.pins.push(PinSpec::Corners(vec![
            Corner::TopLeft,
            Corner::TopRight,
            Corner::BottomLeft,
            Corner::BottomRight,
        ]));
        self
    }

    /// Pins a whole edge.
    pub fn pin_edge(mut self, edge: Edge) -> Self {
        self.pins.push(PinSpec::Edge(edge));
        self
    }

    /// Pins particles by index (`row * cols + col`).
    pub fn pin_indices(mut self, indices: impl IntoIterator<Item = u32>) -> Self {
        self.pins
            .push(PinSpec::Indices(indices.into_iter().collect()));
        self
    }

    /// Pins every particle for which `predicate(row, col, world_position)` is true.
    pub fn pin_where(mut self, predicate: impl Fn(usize, usize, Vec3) -> bool + 'static) -> Self {
        self.pins.push(PinSpec::Predicate(Box::new(predicate)));
        self
    }

    /// Builds the cloth, or says which argument is wrong and what is allowed.
    pub fn build(self) -> Result<Cloth> {
        let allowed_side = format!("2 ..= {MAX_GRID_SIDE}");
        if !(2..=MAX_GRID_SIDE).contains(&self.rows) {
            return Err(ClothError::invalid("grid.rows", self.rows, allowed_side));
        }
        if !(2..=MAX_GRID_SIDE).contains(&self.cols) {
            return Err(ClothError::invalid("grid.cols", self.cols, allowed_side));
        }
        let (dx, dy) = match self.extent {
            Extent::Size { width, height } => {
                check::length("grid.width", width, MAX_CLOTH_EXTENT)?;
                check::length("grid.height", height, MAX_CLOTH_EXTENT)?;
                (
                    width / (self.cols - 1) as f32,
                    height / (self.rows - 1) as f32,
                )
            }
            Extent::Spacing {
                along_cols,
                along_rows,
            } => {
                let (most_cols, most_rows) = (max_spacing(self.cols), max_spacing(self.rows));
                check::length("grid.spacing.along_cols", along_cols, most_cols)?;
                check::length("grid.spacing.along_rows", along_rows, most_rows)?;
                (along_cols, along_rows)
            }
        };
        check::finite_vec("grid.origin", self.origin)?;
        check::finite_vec("grid.velocity", self.velocity)?;
        if !self.rotation.is_finite() || (self.rotation.length() - 1.0).abs() > 1e-3 {
            return Err(ClothError::invalid(
                "grid.rotation",
                self.rotation,
                "a finite unit quaternion",
            ));
        }
        let rotation = self.rotation.normalize();
        let (rows, cols) = (self.rows, self.cols);
        let n = rows * cols;
        let width = dx * (cols - 1) as f32;
        let height = dy * (rows - 1) as f32;

        let mut position = Vec::with_capacity(n);
        for r in 0..rows {
            for c in 0..cols {
                let u = c as f32 * dx - 0.5 * width;
                let v = r as f32 * dy - 0.5 * height;
                let local = match self.orientation {
                    Orientation::Horizontal => Vec3::new(u, 0.0, v),
                    Orientation::Vertical => Vec3::new(u, -v, 0.0),
                };
                position.push(self.origin + rotation * local);
            }
        }
        if let Some(i) = position.iter().position(|p| !p.is_finite()) {
            return Err(ClothError::invalid(
                "grid.size",
                (width, height),
                format!("a size whose positions are finite (particle {i} is not)"),
            ));
        }
        // f32 positions must resolve the spacing where the cloth is: far from the world
        // origin neighbours would round onto one another (springs of zero rest length, strains
        // of 0/0). At least `RESOLVED_ULPS` representable steps per spacing.
        let far = position
            .iter()
            .map(|p| p.abs().max_element())
            .fold(0.0_f32, f32::max);
        let spacing = dx.min(dy);
        let needed = far * f32::EPSILON * RESOLVED_ULPS;
        // Blame the size when the cloth's own extent, not its distance from the origin,
        // puts a particle that far out.
        if spacing < needed && self.origin.abs().max_element() <= 0.5 * width.max(height) {
            let (name, value) = match self.extent {
                Extent::Size { .. } => ("grid.size", (width, height)),
                Extent::Spacing { .. } => ("grid.spacing", (dx, dy)),
            };
            return Err(ClothError::invalid(
                name,
                value,
                format!(
                    "a spacing of at least {needed:.3e} m along both directions, 1/{:.0} of the \
                     farthest particle's distance from the world origin ({far:.3e} m), but \
                     it is {spacing:.3e} m (f32 positions must resolve 1/{RESOLVED_ULPS} of a \
                     spacing): use fewer particles along the short side, or a less \
                     elongated cloth",
                    1.0 / (f32::EPSILON * RESOLVED_ULPS)
                ),
            ));
        }
        if spacing < needed {
            return Err(ClothError::invalid(
                "grid.origin",
                self.origin,
                format!(
                    "every particle within {:.3e} m of the world origin for a spacing of \
                     {spacing:.3e} m (f32 positions must resolve 1/{RESOLVED_ULPS} of a \
                     spacing), but one is {far:.3e} m from it: move the cloth nearer the \
                     origin, or make it larger",
                    spacing / (f32::EPSILON * RESOLVED_ULPS)
                ),
            ));
        }

        let mass = match self.mass {
            Mass::PerParticle(m) => {
                check::positive("grid.mass.per_particle", m)?;
                vec![m; n]
            }
            Mass::ArealDensity(rho) => {
                check::positive("grid.mass.areal_density", rho)?;
                let cell = rho * dx * dy;
                let mut mass = Vec::with_capacity(n);
                for r in 0..rows {
                    let wr = if r == 0 || r == rows - 1 { 0.5 } else { 1.0 };
                    for c in 0..cols {
                        let wc = if c == 0 || c == cols - 1 { 0.5 } else { 1.0 };
                        mass.push(cell * wr * wc);
                    }
                }
                mass
            }
        };
        if let Some((m, allowed)) = mass
            .iter()
            .find_map(|&m| crate::particles::check_mass(m).err().map(|a| (m, a)))
        {
            return Err(ClothError::invalid(
                "grid.mass",
                m,
                format!(
                    "per particle, {allowed}; density × cell area may have underflowed or \
                     overflowed"
                ),
            ));
        }

        let mut pinned = vec![false; n];
        for spec in &self.pins {
            match spec {
                PinSpec::Corners(corners) => {
                    for corner in corners {
                        let (r, c) = match corner {
                            Corner::TopLeft => (0, 0),
                            Corner::TopRight => (0, cols - 1),
                            Corner::BottomLeft => (rows - 1, 0),
                            Corner::BottomRight => (rows - 1, cols - 1),
                        };
                        pinned[r * cols + c] = true;
                    }
                }
                PinSpec::Edge(edge) => {
                    let cells: Vec<usize> = match edge {
                        Edge::Top => (0..cols).collect(),
                        Edge::Bottom => (0..cols).map(|c| (rows - 1) * cols + c).collect(),
                        Edge::Left => (0..rows).map(|r| r * cols).collect(),
                        Edge::Right => (0..rows).map(|r| r * cols + cols - 1).collect(),
                    };
                    for i in cells {
                        pinned[i] = true;
                    }
                }
                PinSpec::Indices(indices) => {
                    for &i in indices {
                        let i = i as usize;
                        if i >= n {
                            return Err(ClothError::IndexOutOfRange {
                                name: "grid.pins".into(),
                                index: i,
                                len: n,
                            });
                        }
                        pinned[i] = true;
                    }
                }
                PinSpec::Predicate(predicate) => {
                    for r in 0..rows {
                        for c in 0..cols {
                            let i = r * cols + c;
                            if predicate(r, c, position[i]) {
                                pinned[i] = true;
                            }
                        }
                    }
                }
            }
        }

        let inv_mass = mass
            .iter()
            .zip(&pinned)
            .map(|(&m, &p)| if p { 0.0 } else { 1.0 / m })
            .collect();
        let velocity = pinned
            .iter()
            .map(|&p| if p { Vec3::ZERO } else { self.velocity })
            .collect();
        let particles = Particles {
            position,
            velocity,
            mass,
            inv_mass,
        };
        let topology = grid_topology(rows, cols, &particles.position);
        Ok(Cloth {
            particles,
            topology,
            rows,
            cols,
        })
    }
}

/// The seed's springs and two triangles per cell for a `rows × cols` grid, rest lengths from
/// `position`.
fn grid_topology(rows: usize, cols: usize, position: &[Vec3]) -> Topology {
    let idx = |r: usize, c: usize| (r * cols + c) as u32;
    let spring = |a: u32, b: u32| Spring {
        a,
        b,
        rest_length: position[a as usize].distance(position[b as usize]),
    };
    let mut warp = Vec::with_capacity((rows - 1) * cols);
    let mut weft = Vec::with_capacity(rows * (cols - 1));
    let mut shear = Vec::with_capacity(2 * (rows - 1) * (cols - 1));
    let mut bend =
        Vec::with_capacity(rows * cols.saturating_sub(2) + cols * rows.saturating_sub(2));
    let mut triangles = Vec::with_capacity(2 * (rows - 1) * (cols - 1));
    for r in 0..rows {
        for c in 0..cols {
            if r + 1 < rows {
                warp.push(spring(idx(r, c), idx(r + 1, c)));
            }
            if c + 1 < cols {
                weft.push(spring(idx(r, c), idx(r, c + 1)));
            }
            if r + 1 < rows && c + 1 < cols {
                shear.push(spring(idx(r, c), idx(r + 1, c + 1)));
                shear.push(spring(idx(r, c + 1), idx(r + 1, c)));
                triangles.push([idx(r, c), idx(r + 1, c), idx(r, c + 1)]);
                triangles.push([idx(r, c + 1), idx(r + 1, c), idx(r + 1, c + 1)]);
            }
            if r + 2 < rows {
                bend.push(spring(idx(r, c), idx(r + 2, c)));
            }
            if c + 2 < cols {
                bend.push(spring(idx(r, c), idx(r, c + 2)));
            }
        }
    }
    let mut per_kind: [Vec<Spring>; 4] = Default::default();
    per_kind[SpringKind::Warp as usize] = warp;
    per_kind[SpringKind::Weft as usize] = weft;
    per_kind[SpringKind::Shear as usize] = shear;
    per_kind[SpringKind::Bend as usize] = bend;
    Topology::new(per_kind, triangles).with_grid(rows, cols)
}
