//! Simulation parameters. Every struct implements `Default`; each field's doc gives its unit
//! and default value. All units are SI.

use glam::Vec3;

use crate::error::{ClothError, Result, check};
use crate::topology::SpringKind;

/// Stiffness and damping of one kind of spring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringParams {
    /// Hooke stiffness k in F = k(|L| − L0)·L/|L|, N/m. Must be finite and `>= 0`.
    pub stiffness: f32,
    /// Dashpot coefficient c along the spring, F = c((v_b − v_a)·d)·d, N·s/m. Must be finite
    /// and `>= 0`.
    pub damping: f32,
}

impl SpringParams {
    /// A spring of stiffness `stiffness` (N/m) and dashpot `damping` (N·s/m).
    #[must_use]
    pub const fn new(stiffness: f32, damping: f32) -> Self {
        Self { stiffness, damping }
    }
}

/// The fabric: spring parameters per kind.
///
/// Defaults: structural 200 N/m with a 0.01 N·s/m dashpot, shear 50 N/m and 0.005 N·s/m,
/// bend 5 N/m and 0.002 N·s/m, warp and weft alike. With the default 32 substeps of a 1/60 s
/// step, symplectic Euler is stable for these on a 1 m, 0.2 kg/m² cloth up to about 40 × 40
/// particles; finer grids need more substeps (the error of an unstable step says how many).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Structural springs along the warp (between rows). Default 200 N/m, 0.01 N·s/m.
    pub warp: SpringParams,
    /// Structural springs along the weft (between columns). Default 200 N/m, 0.01 N·s/m.
    pub weft: SpringParams,
    /// Shear springs (cell diagonals). Default 50 N/m, 0.005 N·s/m.
    pub shear: SpringParams,
    /// Bending springs (two apart). Default 5 N/m, 0.002 N·s/m.
    pub bend: SpringParams,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            warp: SpringParams::new(200.0, 0.01),
            weft: SpringParams::new(200.0, 0.01),
            shear: SpringParams::new(50.0, 0.005),
            bend: SpringParams::new(5.0, 0.002),
        }
    }
}

impl Material {
    /// The same structural parameters along warp and weft.
    #[must_use]
    pub const fn isotropic(
        structural: SpringParams,
        shear: SpringParams,
        bend: SpringParams,
    ) -> Self {
        Self {
            warp: structural,
            weft: structural,
            shear,
            bend,
        }
    }

    /// Parameters of one kind.
    #[must_use]
    pub fn params(&self, kind: SpringKind) -> SpringParams {
        match kind {
            SpringKind::Warp => self.warp,
            SpringKind::Weft => self.weft,
            SpringKind::Shear => self.shear,
            SpringKind::Bend => self.bend,
        }
    }

    fn validate(&self) -> Result<()> {
        for kind in SpringKind::ALL {
            let p = self.params(kind);
            check::non_negative(
                &format!("config.material.{}.stiffness", kind.name()),
                p.stiffness,
            )?;
            check::non_negative(
                &format!("config.material.{}.damping", kind.name()),
                p.damping,
            )?;
        }
        Ok(())
    }
}

/// Periodic gusts on top of the steady wind.
///
/// The wind speed is multiplied by `1 + amplitude · g(t)`, where
/// g(t) = 0.6·sin(2πft) + 0.4·sin(2π·2.37·ft + 1.3) is a smooth, deterministic signal in
/// [−1, 1].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gust {
    /// Relative strength of the gusts, in [0, 1]. Default 0.5.
    pub amplitude: f32,
    /// Base frequency f of the gusts, Hz, `> 0`. Default 0.5 Hz.
    pub frequency: f32,
}

impl Default for Gust {
    fn default() -> Self {
        Self {
            amplitude: 0.5,
            frequency: 0.5,
        }
    }
}

/// Air: per-triangle aerodynamic drag and lift against the wind.
///
/// For each triangle of area A and unit normal n, with the air's velocity relative to the
/// triangle v_rel = wind − (v₀+v₁+v₂)/3 and cos θ = n·v̂_rel:
/// - drag, along the normal: F_d = ½ρ|v_rel|²·C_d·A·cos θ · n (pushes the cloth along the
///   wind's normal component, whichever side the wind comes from);
/// - lift, perpendicular to the wind in the plane of n and v_rel:
///   F_l = ½ρ|v_rel|²·C_l·A·|cos θ|·sin θ · l̂.
///
/// Each triangle's force is shared equally by its three particles. This is the model of
/// NvCloth and Blender's cloth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Air {
    /// Air density ρ, kg/m³, `>= 0`. Default 1.2 kg/m³.
    pub density: f32,
    /// Drag coefficient C_d, dimensionless, `>= 0`. Default 1.0.
    pub drag_coefficient: f32,
    /// Lift coefficient C_l, dimensionless, `>= 0`. Default 0.2.
    pub lift_coefficient: f32,
    /// Steady wind velocity, m/s. Default zero (still air: drag only against the cloth's own
    /// motion).
    pub wind: Vec3,
    /// Optional gusts modulating the wind. Default `None`.
    pub gust: Option<Gust>,
}

impl Default for Air {
    fn default() -> Self {
        Self {
            density: 1.2,
            drag_coefficient: 1.0,
            lift_coefficient: 0.2,
            wind: Vec3::ZERO,
            gust: None,
        }
    }
}

impl Air {
    /// The wind velocity at simulated time `t` (s), gusts included.
    #[must_use]
    pub fn wind_at(&self, t: f64) -> Vec3 {
        match self.gust {
            None => self.wind,
            Some(g) => {
                let phase = std::f64::consts::TAU * f64::from(g.frequency) * t;
                let signal = 0.6 * phase.sin() + 0.4 * (2.37 * phase + 1.3).sin();
                self.wind * (1.0 + g.amplitude * signal as f32)
            }
        }
    }

    fn validate(&self) -> Result<()> {
        check::non_negative("config.air.density", self.density)?;
        check::non_negative("config.air.drag_coefficient", self.drag_coefficient)?;
        check::non_negative("config.air.lift_coefficient", self.lift_coefficient)?;
        check::finite_vec("config.air.wind", self.wind)?;
        if let Some(g) = self.gust {
            check::in_range("config.air.gust.amplitude", g.amplitude, 0.0, 1.0)?;
            check::positive("config.air.gust.frequency", g.frequency)?;
        }
        Ok(())
    }
}

/// Switches for each force term. All on by default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ForceSwitches {
    /// Gravity m·g.
    pub gravity: bool,
    /// Hooke springs.
    pub springs: bool,
    /// Dashpots along the springs.
    pub dashpots: bool,
    /// The seed's global damping −d·v.
    pub damping: bool,
    /// Air drag and lift.
    pub air: bool,
}

impl Default for ForceSwitches {
    fn default() -> Self {
        Self {
            gravity: true,
            springs: true,
            dashpots: true,
            damping: true,
            air: true,
        }
    }
}

/// The time integrator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Integrator {
    /// Forward (explicit) Euler, as the seed paper writes it: x += h·v, then v += h·a(x, v).
    /// First order and unconditionally unstable for undamped springs: its energy grows by a
    /// factor 1 + (ωh)² every step.
    ForwardEuler,
    /// Symplectic (semi-implicit) Euler, what the seed's code does: v += h·a(x, v), then
    /// x += h·v. Stable for h < 2/ω; its energy oscillates but does not drift. The default.
    #[default]
    SymplecticEuler,
    /// Position Verlet (drift–kick–drift, Störmer–Verlet in its position form): x += ½h·v,
    /// v += h·a(x, v), x += ½h·v. Second order and symplectic, one force evaluation per step.
    Verlet,
    /// Linearised backward Euler (Baraff & Witkin 1998): one linear solve per substep by
    /// filtered preconditioned conjugate gradients ([`ImplicitSettings`]). Stable at large
    /// steps; dissipates energy.
    ImplicitEuler,
    /// Extended position-based dynamics (Macklin et al. 2016, 2019): springs as compliant
    /// distance constraints with compliance 1/k, Gauss–Seidel sweeps ([`XpbdSettings`]).
    /// Stable at any step; stiffness converges to the material's as substeps grow.
    Xpbd,
}

impl Integrator {
    /// All integrators.
    pub const ALL: [Integrator; 5] = [
        Self::ForwardEuler,
        Self::SymplecticEuler,
        Self::Verlet,
        Self::ImplicitEuler,
        Self::Xpbd,
    ];

    /// The explicit, force-based integrators (stable only below a step set by stiffness).
    pub const EXPLICIT: [Integrator; 3] = [Self::ForwardEuler, Self::SymplecticEuler, Self::Verlet];

    /// The integrator called `name` (see [`Integrator::name`]).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|i| i.name() == name)
    }

    /// `true` for the explicit integrators, whose stable step is bounded by the stiffness.
    #[must_use]
    pub fn is_explicit(self) -> bool {
        Self::EXPLICIT.contains(&self)
    }

    /// Short name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::ForwardEuler => "forward-euler",
            Self::SymplecticEuler => "symplectic-euler",
            Self::Verlet => "verlet",
            Self::ImplicitEuler => "implicit-euler",
            Self::Xpbd => "xpbd",
        }
    }
}

/// Settings of the implicit Euler solver's conjugate gradient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitSettings {
    /// Relative residual (preconditioned norm) at which CG stops, in (0, 1): relative to the
    /// larger of the right-hand side and one substep's gravity impulse on the cloth (so that a
    /// cloth at rest, whose right-hand side is almost zero, is not solved to a finer absolute
    /// accuracy than a falling one). Default 1e-3.
    pub tolerance: f32,
    /// Iteration cap per substep, `>= 1`. Default 200. A solve that hits it is reported in
    /// [`StepStats::solver`](crate::StepStats::solver) as not converged.
    pub max_iterations: u32,
}

impl Default for ImplicitSettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-3,
            max_iterations: 200,
        }
    }
}

/// Settings of the XPBD solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct XpbdSettings {
    /// Gauss–Seidel sweeps per substep, `>= 1`. Default 1: Macklin et al. 2019 show that, for
    /// the same cost, more substeps with one sweep each give a stiffer, more accurate cloth
    /// than fewer substeps with many sweeps.
    pub iterations: u32,
    /// Long-range attachments ("tethers", as in NvCloth): every free particle may be at most
    /// its rest distance to the nearest pinned particle (times 1 + `tether_slack`) away from
    /// it. Stops stretchy hanging cloth. Default off.
    pub tethers: bool,
    /// Extra length allowed to tethers, as a fraction of their rest length, `>= 0`. Default
    /// 0.02.
    pub tether_slack: f32,
    /// Multi-resolution strain limits (after Wang, O'Brien & Ramamoorthi 2010): particles 2,
    /// 4, …, 2^`hierarchy_levels` apart along the warp and along the weft of a grid cloth are
    /// kept at most (1 + `hierarchy_slack`) times their rest distance apart, projected after
    /// the springs in every sweep. A pull then crosses 2^levels particles in one sweep instead
    /// of one particle per sweep, so a large cloth stops stretching with few substeps.
    /// `0 ..= 16`; default 0 (off). Ignored on a cloth that is not a grid.
    pub hierarchy_levels: u32,
    /// Extra length allowed by the strain limits, as a fraction of the rest distance, `>= 0`.
    /// Default 0.02.
    pub hierarchy_slack: f32,
    /// Strain limit of the structural springs (after Provot 1995): with `Some(s)`, every warp
    /// and weft spring is kept at most (1 + s) times its rest length, a one-sided,
    /// inextensible limit projected after the springs (and the chain solves) in every sweep,
    /// before the multi-resolution limits. Woven fabric stiffens sharply past a few per cent
    /// of stretch; a spring model with a finite stiffness, solved with few substeps, can leave
    /// a spring stretched far past that where a cell has collapsed in shear (the warp's and
    /// the weft's solves then undo one another), and the limit holds it. `0 ..= 1` (0.02 =
    /// 2 %); default `None` (off). [`SimConfig::strain_limit`] is the force-based
    /// integrators' counterpart.
    pub structural_limit: Option<f32>,
    /// Solve the warp and weft springs of a grid cloth **chain by chain** (every column's warp
    /// springs, then every row's weft springs), each chain's multipliers together by a
    /// tridiagonal solve, instead of spring by spring. A pull then crosses the whole cloth in
    /// one sweep, so a hanging or draped cloth stops stretching with few substeps; the
    /// constraints and their compliance are the same. The structural springs are then solved
    /// last in each sweep (after shear and bend), so a sweep ends with them satisfied.
    /// Default `false`. Ignored on a cloth that is not a grid.
    pub chains: bool,
    /// Newton iterations of each chain solve (with `chains`), `1 ..= 16`: the chain's
    /// directions and constraint values are taken again from the positions the previous
    /// iteration left, and its multipliers keep what the previous iterations added. One
    /// iteration linearises the chain once, so the sideways pull of a taut chain (its
    /// geometric stiffness) acts explicitly: at large substeps (h·√(4T/(m·l)) above about 1,
    /// T the chain's tension, m a particle's mass, l the spring length) a zigzag across the
    /// chain grows and the cloth crumples. Two or three iterations make the projection close
    /// to the chain's exact (nonlinear) one and keep the chains straight with several times
    /// fewer substeps. Default 1.
    pub chain_iterations: u32,
    /// Rounds of chain solves per sweep (with `chains`), `1 ..= 16`. With more than one, the
    /// warp and weft chain solves run `chain_rounds` times in turn, each round after a pass of
    /// collider contacts, and the chains' multipliers keep what the earlier rounds added
    /// (block Gauss–Seidel between the two directions, with the contacts inside it). One
    /// round leaves the warp disturbed by the weft solved after it, most where the cloth
    /// wraps a collider (a grid cannot lie on a sphere without shearing) and where the
    /// contacts, projected after the chains, push out the particles the chains pulled in; a
    /// second round corrects both for the price of the chain solves and a contact pass,
    /// less than the substeps it saves. Default 1 (and then no contact pass before the
    /// chains).
    pub chain_rounds: u32,
    /// Relaxation ω of the chain solves (with `chains` or `shear_chains`), `0 < ω < 2`: each
    /// solve's multiplier changes, and so its moves, are ω times the Newton step's (successive
    /// over-relaxation of the Gauss–Seidel between the warp, the weft and the contacts). Where
    /// a cloth lands on a collider, the contacts and the other direction undo part of each chain
    /// solve in every round, and over-relaxation makes up for it: the 512² drape holds its
    /// structural strain under 10 % at 4 substeps of four chain rounds with ω = 1.3, where
    /// ω = 1 needs five (`docs/performance.md`). An over-relaxed solve leaves |1 − ω| of the
    /// error it corrects, so a substep's rounds × `chain_iterations` solves leave about
    /// |1 − ω|ⁿ of it: with four rounds of two iterations at ω = 1.3 a hanging cloth settles
    /// where the plain step puts it (to 10⁻⁴ of its stretch), with one round of one iteration
    /// 25 % of its stretch away. Use it with several rounds. Default 1 (the plain Newton step;
    /// the same bits as without it).
    pub chain_relaxation: f32,
    /// Solve the shear springs of a grid cloth **chain by chain** too: every diagonal line of
    /// the grid (the springs `(r, c)–(r + 1, c + 1)` one after the other), then every
    /// anti-diagonal line (`(r, c)–(r + 1, c − 1)`), each line's multipliers together by the
    /// same tridiagonal solve as `chains` (and with its `chain_iterations`), instead of
    /// spring by spring. A shear then crosses the cloth in one solve instead of one cell
    /// per substep: a cloth wrapping a collider finds its sheared shape with a fraction of
    /// the substeps (the 256² drape at 20 substeps stores 0.07 J in its springs instead of
    /// 0.41 J; the converged drape, 32 substeps of two sweeps without it, 0.06 J), for about
    /// 40 % more time per substep. Default `false`. Ignored on a cloth
    /// that is not a grid.
    pub shear_chains: bool,
    /// Project the shear springs of a grid cloth **row by row**, on the grid path and the
    /// reference path alike: cell row after cell row, each row's diagonals and then its
    /// anti-diagonals, a Gauss–Seidel sweep in the order of the rows, instead of in two colours
    /// of alternate rows (grid path) or in storage order (reference path). A correction then
    /// crosses the cloth in one sweep instead of one row per sweep, and the shear springs and
    /// the chain solves stop undoing one another on a collider's curved surface: the 512² drape
    /// holds its structural strain under 10 % at 6 substeps of three chain rounds instead of 10
    /// of two. The rows split into two halves swept at the same time and the row between them,
    /// so the result is the same for any thread count; the reference path sweeps in the same
    /// order. The same constraints and compliance; only the order of the sweep changes. The
    /// real-time settings (`presets::realtime_drape`) turn it on. It is off by default because
    /// with many substeps of one chain round it is not better everywhere: the 128² `xpbd-drape`
    /// scene (20 substeps) stores less energy with it but settles with a warp spring at 2.5 %
    /// instead of 1.5 %. Default `false`. Ignored with `shear_chains` and on a cloth that is
    /// not a grid.
    pub shear_rows: bool,
}

impl XpbdSettings {
    /// The allowed values of [`Self::chain_relaxation`], as its errors state them.
    pub(crate) const CHAIN_RELAXATION_RANGE: &'static str = "greater than 0 and less than 2";

    /// Whether `omega` is an allowed [`Self::chain_relaxation`] (finite, `0 < ω < 2`).
    pub(crate) fn chain_relaxation_allowed(omega: f32) -> bool {
        omega.is_finite() && omega > 0.0 && omega < 2.0
    }
}

impl Default for XpbdSettings {
    fn default() -> Self {
        Self {
            iterations: 1,
            tethers: false,
            tether_slack: 0.02,
            hierarchy_levels: 0,
            hierarchy_slack: 0.02,
            structural_limit: None,
            chains: false,
            chain_iterations: 1,
            chain_rounds: 1,
            chain_relaxation: 1.0,
            shear_chains: false,
            shear_rows: false,
        }
    }
}

/// Limits past which a step is reported as unstable instead of accepted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilityLimits {
    /// Largest allowed spring length as a multiple of its rest length. Default 10.
    /// Must be `> 1`.
    pub max_stretch_ratio: f32,
    /// Largest allowed particle speed, m/s. Default 1000 m/s. Must be `> 0`.
    pub max_speed: f32,
}

impl Default for StabilityLimits {
    fn default() -> Self {
        Self {
            max_stretch_ratio: 10.0,
            max_speed: 1000.0,
        }
    }
}

/// Everything a [`Simulation`](crate::Simulation) needs besides the cloth and colliders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// Time step of one call to [`step`](crate::Simulation::step), s. Default 1/60 s.
    /// Must be finite, with `dt / substeps` at least [`MIN_SUBSTEP_DT`] (1 ns).
    pub dt: f32,
    /// Substeps per step: each substep advances dt/substeps. Default 32. `1 ..= 100000`.
    pub substeps: u32,
    /// The integrator. Default [`Integrator::SymplecticEuler`].
    pub integrator: Integrator,
    /// Gravitational acceleration, m/s². Default (0, −9.81, 0).
    pub gravity: Vec3,
    /// The seed's global damping d in F = −d·v, per particle, N·s/m. Default 0.002 N·s/m.
    pub damping: f32,
    /// Spring parameters.
    pub material: Material,
    /// Air and wind.
    pub air: Air,
    /// Which force terms are on.
    pub forces: ForceSwitches,
    /// Instability thresholds.
    pub limits: StabilityLimits,
    /// Provot-style strain limiting for the force-based integrators: after each substep,
    /// structural and shear springs stretched past (1 + limit)·L0 are shortened back to it
    /// (positions and velocities corrected, mass-weighted). `None` (the default) is off;
    /// otherwise `> 0`, e.g. 0.1 for 10 %. XPBD does not read it: its counterpart, a
    /// constraint inside its sweeps, is [`XpbdSettings::structural_limit`].
    pub strain_limit: Option<f32>,
    /// Implicit Euler settings.
    pub implicit: ImplicitSettings,
    /// XPBD settings.
    pub xpbd: XpbdSettings,
    /// Cloth–cloth contact (particles keep a thickness from each other). `None` (the
    /// default) is off.
    pub self_collision: Option<crate::collide::self_collision::SelfCollision>,
    /// Continuous collision against the colliders (see [`crate::collide::ccd`]): after each
    /// substep, a particle whose path went through a collider is put back on the side it came
    /// from. Default `true`.
    pub continuous_collision: bool,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            dt: 1.0 / 60.0,
            substeps: 32,
            integrator: Integrator::default(),
            gravity: Vec3::new(0.0, -9.81, 0.0),
            damping: 0.002,
            material: Material::default(),
            air: Air::default(),
            forces: ForceSwitches::default(),
            limits: StabilityLimits::default(),
            strain_limit: None,
            implicit: ImplicitSettings::default(),
            xpbd: XpbdSettings::default(),
            self_collision: None,
            continuous_collision: true,
        }
    }
}

/// Largest number of substeps per step.
pub const MAX_SUBSTEPS: u32 = 100_000;

/// Shortest substep dt/substeps, s (1 ns): far below any cloth's stability limit, and far
/// above where a substep's Δx/h and 1/h² leave f32's range.
pub const MIN_SUBSTEP_DT: f32 = 1.0e-9;

impl SimConfig {
    /// Checks every field; the error names the first bad one and its allowed range.
    pub fn validate(&self) -> Result<()> {
        check::positive("config.dt", self.dt)?;
        if !(1..=MAX_SUBSTEPS).contains(&self.substeps) {
            return Err(ClothError::invalid(
                "config.substeps",
                self.substeps,
                format!("1 ..= {MAX_SUBSTEPS}"),
            ));
        }
        if self.substep_dt() < MIN_SUBSTEP_DT {
            return Err(ClothError::invalid(
                "config.dt",
                self.dt,
                format!(
                    "a step whose substeps (dt / {} substeps = {:e} s) are at least \
                     {MIN_SUBSTEP_DT:e} s",
                    self.substeps,
                    self.substep_dt()
                ),
            ));
        }
        check::finite_vec("config.gravity", self.gravity)?;
        check::non_negative("config.damping", self.damping)?;
        self.material.validate()?;
        self.air.validate()?;
        if !(self.limits.max_stretch_ratio.is_finite() && self.limits.max_stretch_ratio > 1.0) {
            return Err(ClothError::invalid(
                "config.limits.max_stretch_ratio",
                self.limits.max_stretch_ratio,
                "a finite number > 1",
            ));
        }
        check::positive("config.limits.max_speed", self.limits.max_speed)?;
        if let Some(limit) = self.strain_limit {
            check::positive("config.strain_limit", limit)?;
        }
        if !(self.implicit.tolerance.is_finite()
            && self.implicit.tolerance > 0.0
            && self.implicit.tolerance < 1.0)
        {
            return Err(ClothError::invalid(
                "config.implicit.tolerance",
                self.implicit.tolerance,
                "a number in (0, 1)",
            ));
        }
        if self.implicit.max_iterations == 0 {
            return Err(ClothError::invalid(
                "config.implicit.max_iterations",
                self.implicit.max_iterations,
                "an integer >= 1",
            ));
        }
        if !(1..=1000).contains(&self.xpbd.iterations) {
            return Err(ClothError::invalid(
                "config.xpbd.iterations",
                self.xpbd.iterations,
                "1 ..= 1000",
            ));
        }
        check::non_negative("config.xpbd.tether_slack", self.xpbd.tether_slack)?;
        if self.xpbd.hierarchy_levels > 16 {
            return Err(ClothError::invalid(
                "config.xpbd.hierarchy_levels",
                self.xpbd.hierarchy_levels,
                "0 ..= 16",
            ));
        }
        check::non_negative("config.xpbd.hierarchy_slack", self.xpbd.hierarchy_slack)?;
        if let Some(limit) = self.xpbd.structural_limit {
            check::in_range("config.xpbd.structural_limit", limit, 0.0, 1.0)?;
        }
        if !(1..=16).contains(&self.xpbd.chain_iterations) {
            return Err(ClothError::invalid(
                "config.xpbd.chain_iterations",
                self.xpbd.chain_iterations,
                "1 ..= 16",
            ));
        }
        if !(1..=16).contains(&self.xpbd.chain_rounds) {
            return Err(ClothError::invalid(
                "config.xpbd.chain_rounds",
                self.xpbd.chain_rounds,
                "1 ..= 16",
            ));
        }
        let omega = self.xpbd.chain_relaxation;
        if !XpbdSettings::chain_relaxation_allowed(omega) {
            return Err(ClothError::invalid(
                "config.xpbd.chain_relaxation",
                omega,
                XpbdSettings::CHAIN_RELAXATION_RANGE,
            ));
        }
        if let Some(sc) = self.self_collision {
            check::positive("config.self_collision.thickness", sc.thickness)?;
            check::non_negative("config.self_collision.friction", sc.friction)?;
        }
        Ok(())
    }

    /// The substep length h = dt / substeps, s.
    #[must_use]
    pub fn substep_dt(&self) -> f32 {
        self.dt / self.substeps as f32
    }
}
