//! Model and API tests: the grid's topology, masses and geometry, argument validation,
//! determinism, instability reporting and pins.

use cloth_core::glam::{EulerRot, Quat, Vec3};
use cloth_core::{
    Air, ClothError, Collider, Corner, Edge, ForceSwitches, Friction, GridBuilder, Gust,
    Integrator, Mass, Material, Orientation, SimConfig, Simulation, SpringKind, SpringParams,
    StabilityLimits,
};

const SIZES: [(usize, usize); 5] = [(2, 2), (2, 5), (7, 3), (5, 9), (32, 32)];

fn unwrap_invalid(err: &ClothError) -> (&str, &str, &str) {
    match err {
        ClothError::InvalidArgument {
            name,
            value,
            allowed,
        } => (name.as_str(), value.as_str(), allowed.as_str()),
        other => panic!("expected InvalidArgument, got {other:?}"),
    }
}

/// Asserts `result` is an `InvalidArgument` for `field` whose Display names the field and
/// contains `allowed_fragment` (the allowed range, in words).
#[track_caller]
fn assert_invalid<T: std::fmt::Debug>(
    result: Result<T, ClothError>,
    field: &str,
    allowed_fragment: &str,
) {
    let err = result.expect_err("expected an error");
    let (name, _, allowed) = unwrap_invalid(&err);
    assert_eq!(name, field, "wrong field in {err}");
    assert!(
        allowed.contains(allowed_fragment),
        "allowed range {allowed:?} of {field} lacks {allowed_fragment:?}"
    );
    let text = err.to_string();
    assert!(text.contains(field), "{text:?} does not name {field}");
    assert!(
        text.contains(allowed_fragment),
        "{text:?} does not give the allowed range {allowed_fragment:?}"
    );
}

// ---------------------------------------------------------------------------------------
// 1. Topology
// ---------------------------------------------------------------------------------------

/// Spring and triangle counts equal their closed formulas for a rows × cols grid:
/// warp (rows−1)·cols, weft rows·(cols−1), shear 2(rows−1)(cols−1),
/// bend rows·(cols−2)+cols·(rows−2), triangles 2(rows−1)(cols−1). Exact (integer) equality.
#[test]
fn spring_and_triangle_counts_match_closed_formulas() {
    for (rows, cols) in SIZES {
        let cloth = GridBuilder::new(rows, cols).build().unwrap();
        let t = &cloth.topology;
        assert_eq!(t.springs_of(SpringKind::Warp).len(), (rows - 1) * cols);
        assert_eq!(t.springs_of(SpringKind::Weft).len(), rows * (cols - 1));
        assert_eq!(
            t.springs_of(SpringKind::Shear).len(),
            2 * (rows - 1) * (cols - 1)
        );
        assert_eq!(
            t.springs_of(SpringKind::Bend).len(),
            rows * (cols - 2) + cols * (rows - 2),
            "bend count for {rows}x{cols}"
        );
        assert_eq!(t.triangles().len(), 2 * (rows - 1) * (cols - 1));
        let total: usize = SpringKind::ALL.iter().map(|&k| t.springs_of(k).len()).sum();
        assert_eq!(t.springs().len(), total);
        assert_eq!(
            t.count_of_class(cloth_core::SpringClass::Structural),
            (rows - 1) * cols + rows * (cols - 1)
        );
        assert_eq!(cloth.particles.len(), rows * cols);
        assert_eq!((cloth.rows, cloth.cols), (rows, cols));
    }
}

/// Every spring starts at rest: its rest length equals the initial distance of its ends
/// (bit-for-bit: both are the same f32 `distance` of the same positions). Indices are in
/// range, the two ends differ, each kind joins the grid neighbours it names (warp one row
/// apart, weft one column, shear one of each, bend two rows or two columns), and no pair
/// of particles is joined twice (checked by sorting the unordered pairs).
#[test]
fn springs_start_at_rest_in_range_and_unique() {
    for (rows, cols) in SIZES {
        let cloth = GridBuilder::new(rows, cols)
            .size(1.3, 0.7)
            .rotation(Quat::from_rotation_x(0.3))
            .origin(Vec3::new(0.5, 2.0, -1.0))
            .build()
            .unwrap();
        let n = cloth.particles.len();
        let x = &cloth.particles.position;
        let mut pairs = Vec::new();
        for kind in SpringKind::ALL {
            for s in cloth.topology.springs_of(kind) {
                let (a, b) = (s.a as usize, s.b as usize);
                assert!(a < n && b < n, "spring {s:?} out of range");
                assert_ne!(a, b);
                assert_eq!(s.rest_length, x[a].distance(x[b]), "{kind:?} {s:?}");
                assert!(s.rest_length > 0.0);
                let (ra, ca) = (a / cols, a % cols);
                let (rb, cb) = (b / cols, b % cols);
                let dr = ra.abs_diff(rb);
                let dc = ca.abs_diff(cb);
                let expected = match kind {
                    SpringKind::Warp => (1, 0),
                    SpringKind::Weft => (0, 1),
                    SpringKind::Shear => (1, 1),
                    SpringKind::Bend => {
                        if dr == 0 {
                            (0, 2)
                        } else {
                            (2, 0)
                        }
                    }
                };
                assert_eq!((dr, dc), expected, "{kind:?} spring {s:?}");
                pairs.push((a.min(b), a.max(b)));
            }
        }
        let before = pairs.len();
        pairs.sort_unstable();
        pairs.dedup();
        assert_eq!(pairs.len(), before, "duplicate springs in {rows}x{cols}");
        for tri in cloth.topology.triangles() {
            assert!(tri.iter().all(|&i| (i as usize) < n));
            assert!(tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]);
        }
    }
}

// ---------------------------------------------------------------------------------------
// 2. Mass
// ---------------------------------------------------------------------------------------

/// Areal density ρ spreads to a total mass ρ·W·H (relative error ≤ 1e-5: an f32 sum of up
/// to 1024 terms); interior particles get a cell ρ·dx·dy, edge particles half a cell,
/// corners a quarter (relative 1e-6: one f32 product each). Per-particle mass m gives n·m
/// (relative 1e-6: the sum is exact up to the final rounding to f32).
#[test]
fn mass_distribution_matches_areal_density() {
    let rho = 0.37_f32;
    for (rows, cols) in SIZES {
        let (w, h) = (1.7_f32, 0.9_f32);
        let cloth = GridBuilder::new(rows, cols)
            .size(w, h)
            .mass(Mass::ArealDensity(rho))
            .build()
            .unwrap();
        let p = &cloth.particles;
        let total = f64::from(p.total_mass());
        let expected = f64::from(rho) * f64::from(w) * f64::from(h);
        assert!(
            ((total - expected) / expected).abs() < 1e-5,
            "{rows}x{cols}: total {total} vs {expected}"
        );
        let cell =
            f64::from(rho) * f64::from(w) / (cols - 1) as f64 * f64::from(h) / (rows - 1) as f64;
        for r in 0..rows {
            for c in 0..cols {
                let edge_r = r == 0 || r == rows - 1;
                let edge_c = c == 0 || c == cols - 1;
                let factor = match (edge_r, edge_c) {
                    (true, true) => 0.25,
                    (true, false) | (false, true) => 0.5,
                    (false, false) => 1.0,
                };
                let m = f64::from(p.mass[cloth.index(r, c)]);
                assert!(
                    ((m - factor * cell) / (factor * cell)).abs() < 1e-6,
                    "({r}, {c}): {m} vs {}",
                    factor * cell
                );
                assert_eq!(
                    p.inv_mass[cloth.index(r, c)],
                    1.0 / p.mass[cloth.index(r, c)]
                );
            }
        }

        let m = 0.013_f32;
        let cloth = GridBuilder::new(rows, cols)
            .mass(Mass::PerParticle(m))
            .build()
            .unwrap();
        assert!(cloth.particles.mass.iter().all(|&x| x == m));
        let total = f64::from(cloth.particles.total_mass());
        let expected = (rows * cols) as f64 * f64::from(m);
        assert!(
            ((total - expected) / expected).abs() < 1e-6,
            "{rows}x{cols}: total {total} vs {expected}"
        );
    }
}

/// Regression: `total_mass`, `center_of_mass` and `momentum` of a million equal particles
/// are exact to f32 rounding of the result (relative 1e-6). A plain f32 running sum is off
/// by 0.5% here, and stalls completely past 2^24 particles.
#[test]
fn particle_sums_are_accurate_for_a_million_particles() {
    let n = 1_000_000;
    let m = 0.013_f32;
    let particles = cloth_core::Particles {
        position: vec![Vec3::new(1.0, -2.0, 0.5); n],
        velocity: vec![Vec3::new(0.3, 0.0, -0.7); n],
        mass: vec![m; n],
        inv_mass: vec![1.0 / m; n],
    };
    let expected = n as f64 * f64::from(m);
    let total = f64::from(particles.total_mass());
    assert!(
        ((total - expected) / expected).abs() < 1e-6,
        "{total} vs {expected}"
    );
    let com = particles.center_of_mass();
    assert!(com.abs_diff_eq(Vec3::new(1.0, -2.0, 0.5), 1e-6), "{com}");
    let p = particles.momentum();
    let expected_p = Vec3::new(0.3, 0.0, -0.7) * expected as f32;
    assert!(
        (p - expected_p).length() < 1e-6 * expected_p.length(),
        "{p}"
    );
}

// ---------------------------------------------------------------------------------------
// 3. Geometry and pins
// ---------------------------------------------------------------------------------------

fn triangle_normal(x: &[Vec3], tri: [u32; 3]) -> Vec3 {
    let [a, b, c] = tri.map(|i| x[i as usize]);
    (b - a).cross(c - a).normalize()
}

/// A horizontal grid lies in the plane y = origin.y (exactly: the local y is 0 and the
/// rotation is the identity), spans width × height centred on the origin (1e-6 m), has
/// columns along +X and rows along +Z, and every triangle winds counter-clockwise around
/// +Y: (b − a) × (c − a) normalised equals +Y within 1e-6.
#[test]
fn horizontal_grid_geometry_and_winding() {
    let origin = Vec3::new(0.25, 1.5, -0.75);
    let cloth = GridBuilder::new(5, 9)
        .size(2.0, 1.0)
        .origin(origin)
        .build()
        .unwrap();
    let x = &cloth.particles.position;
    assert!(x.iter().all(|p| p.y == origin.y));
    let first = x[cloth.index(0, 0)];
    let last = x[cloth.index(4, 8)];
    assert!(first.abs_diff_eq(origin + Vec3::new(-1.0, 0.0, -0.5), 1e-6));
    assert!(last.abs_diff_eq(origin + Vec3::new(1.0, 0.0, 0.5), 1e-6));
    // columns along +X, rows along +Z
    assert!((x[cloth.index(0, 1)] - first).abs_diff_eq(Vec3::new(0.25, 0.0, 0.0), 1e-6));
    assert!((x[cloth.index(1, 0)] - first).abs_diff_eq(Vec3::new(0.0, 0.0, 0.25), 1e-6));
    for &tri in cloth.topology.triangles() {
        assert!(
            triangle_normal(x, tri).abs_diff_eq(Vec3::Y, 1e-6),
            "{tri:?}"
        );
    }
}

/// A vertical grid lies in z = origin.z, row 0 is the top edge (y = origin.y + H/2, the
/// last row at origin.y − H/2, within 1e-6 m), columns run along +X, and every triangle's
/// normal is +Z within 1e-6.
#[test]
fn vertical_grid_row_zero_is_top_and_normal_is_z() {
    let origin = Vec3::new(0.0, 2.0, 0.5);
    let cloth = GridBuilder::new(6, 4)
        .size(0.6, 1.0)
        .orientation(Orientation::Vertical)
        .origin(origin)
        .build()
        .unwrap();
    let x = &cloth.particles.position;
    assert!(x.iter().all(|p| p.z == origin.z));
    for c in 0..4 {
        assert!((x[cloth.index(0, c)].y - 2.5).abs() < 1e-6);
        assert!((x[cloth.index(5, c)].y - 1.5).abs() < 1e-6);
    }
    for r in 0..5 {
        assert!(x[cloth.index(r, 0)].y > x[cloth.index(r + 1, 0)].y);
    }
    assert!((x[cloth.index(0, 3)].x - x[cloth.index(0, 0)].x - 0.6).abs() < 1e-6);
    for &tri in cloth.topology.triangles() {
        assert!(
            triangle_normal(x, tri).abs_diff_eq(Vec3::Z, 1e-6),
            "{tri:?}"
        );
    }
}

/// The rotation turns the grid about its origin: each particle of the rotated grid equals
/// origin + q·(local position of the unrotated grid at the world origin) within 1e-5 m, and
/// the triangle normals become q·(+Y) within 1e-5.
#[test]
fn rotation_and_origin_are_applied() {
    let q = Quat::from_euler(EulerRot::XYZ, 0.4, -1.1, 0.7);
    let origin = Vec3::new(3.0, -2.0, 1.0);
    let flat = GridBuilder::new(4, 7).size(1.2, 0.8).build().unwrap();
    let turned = GridBuilder::new(4, 7)
        .size(1.2, 0.8)
        .rotation(q)
        .origin(origin)
        .build()
        .unwrap();
    for (a, b) in flat
        .particles
        .position
        .iter()
        .zip(&turned.particles.position)
    {
        assert!((origin + q * *a).abs_diff_eq(*b, 1e-5), "{a} -> {b}");
    }
    let normal = q * Vec3::Y;
    for &tri in turned.topology.triangles() {
        assert!(triangle_normal(&turned.particles.position, tri).abs_diff_eq(normal, 1e-5));
    }
}

/// `spacing(dx, dy)` gives neighbours exactly dx apart along the columns and dy along the
/// rows (1e-6 m: f32 products of spacing and small integers), whatever the grid size; the
/// overall size is then dx·(cols−1) × dy·(rows−1).
#[test]
fn spacing_gives_exact_neighbour_distances() {
    let (dx, dy) = (0.05_f32, 0.08_f32);
    let cloth = GridBuilder::new(7, 11).spacing(dx, dy).build().unwrap();
    for s in cloth.topology.springs_of(SpringKind::Weft) {
        assert!((s.rest_length - dx).abs() < 1e-6, "{}", s.rest_length);
    }
    for s in cloth.topology.springs_of(SpringKind::Warp) {
        assert!((s.rest_length - dy).abs() < 1e-6, "{}", s.rest_length);
    }
    let x = &cloth.particles.position;
    let span = x[cloth.index(6, 10)] - x[cloth.index(0, 0)];
    assert!(span.abs_diff_eq(Vec3::new(10.0 * dx, 0.0, 6.0 * dy), 1e-6));
}

fn pinned_set(cloth: &cloth_core::Cloth) -> Vec<usize> {
    (0..cloth.particles.len())
        .filter(|&i| cloth.particles.inv_mass[i] == 0.0)
        .collect()
}

/// Each pin specification pins exactly the particles it names (inv_mass == 0, velocity
/// zero even with an initial velocity, mass kept) and no others.
#[test]
fn pins_select_exactly_the_right_particles() {
    let (rows, cols) = (4, 5);
    let b = || GridBuilder::new(rows, cols).velocity(Vec3::new(0.0, -1.0, 0.0));
    let idx = |r: usize, c: usize| r * cols + c;

    let cases: Vec<(GridBuilder, Vec<usize>)> = vec![
        (b(), vec![]),
        (
            b().pin_corners(),
            vec![idx(0, 0), idx(0, 4), idx(3, 0), idx(3, 4)],
        ),
        (b().pin_corner(Corner::TopLeft), vec![idx(0, 0)]),
        (b().pin_corner(Corner::TopRight), vec![idx(0, 4)]),
        (b().pin_corner(Corner::BottomLeft), vec![idx(3, 0)]),
        (b().pin_corner(Corner::BottomRight), vec![idx(3, 4)]),
        (
            b().pin_corner(Corner::TopLeft)
                .pin_corner(Corner::BottomRight),
            vec![idx(0, 0), idx(3, 4)],
        ),
        (
            b().pin_edge(Edge::Top),
            (0..cols).map(|c| idx(0, c)).collect(),
        ),
        (
            b().pin_edge(Edge::Bottom),
            (0..cols).map(|c| idx(3, c)).collect(),
        ),
        (
            b().pin_edge(Edge::Left),
            (0..rows).map(|r| idx(r, 0)).collect(),
        ),
        (
            b().pin_edge(Edge::Right),
            (0..rows).map(|r| idx(r, 4)).collect(),
        ),
        (b().pin_indices([7, 3, 19, 3]), vec![3, 7, 19]),
        (
            b().pin_where(|r, c, _| (r + c) % 3 == 0),
            (0..rows * cols)
                .filter(|i| (i / cols + i % cols) % 3 == 0)
                .collect(),
        ),
        (
            // predicate on world position: the x > 0 half (columns 3 and 4 of 0..5)
            b().pin_where(|_, _, x| x.x > 0.01),
            (0..rows * cols).filter(|i| i % cols >= 3).collect(),
        ),
    ];
    for (i, (builder, mut expected)) in cases.into_iter().enumerate() {
        let cloth = builder.build().unwrap();
        expected.sort_unstable();
        assert_eq!(pinned_set(&cloth), expected, "case {i}");
        for j in 0..cloth.particles.len() {
            assert!(cloth.particles.mass[j] > 0.0);
            let v = cloth.particles.velocity[j];
            if cloth.particles.is_pinned(j) {
                assert_eq!(v, Vec3::ZERO);
            } else {
                assert_eq!(v, Vec3::new(0.0, -1.0, 0.0));
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// 4. Builder argument errors
// ---------------------------------------------------------------------------------------

/// Bad builder arguments return `InvalidArgument` (no panic) naming the argument and
/// giving its allowed range.
#[test]
fn bad_builder_arguments_are_errors_naming_the_argument() {
    let g = || GridBuilder::new(4, 4);
    assert_invalid(GridBuilder::new(1, 4).build(), "grid.rows", "2 ..= 8192");
    assert_invalid(GridBuilder::new(0, 4).build(), "grid.rows", "2 ..= 8192");
    assert_invalid(GridBuilder::new(4, 1).build(), "grid.cols", "2 ..= 8192");
    assert_invalid(GridBuilder::new(4, 9000).build(), "grid.cols", "2 ..= 8192");
    // Lengths: the cloth at most 10 km wide and high (spacing × 3 on a 4 × 4 grid), far
    // below where f32 squared lengths overflow.
    for bad in [
        0.0,
        -1.0,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1.0e30,
        10_001.0,
    ] {
        assert_invalid(g().size(bad, 1.0).build(), "grid.width", "(0, 10000] m");
        assert_invalid(g().size(1.0, bad).build(), "grid.height", "(0, 10000] m");
    }
    assert!(g().size(10_000.0, 10_000.0).build().is_ok());
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, 1.0e30, 3334.0] {
        assert_invalid(
            g().spacing(bad, 0.1).build(),
            "grid.spacing.along_cols",
            "(0, 3333.3333] m",
        );
        assert_invalid(
            g().spacing(0.1, bad).build(),
            "grid.spacing.along_rows",
            "(0, 3333.3333] m",
        );
    }
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert_invalid(
            g().mass(Mass::PerParticle(bad)).build(),
            "grid.mass.per_particle",
            "> 0",
        );
        assert_invalid(
            g().mass(Mass::ArealDensity(bad)).build(),
            "grid.mass.areal_density",
            "> 0",
        );
    }
    for bad in [
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::new(0.0, f32::INFINITY, 0.0),
        Vec3::new(0.0, 0.0, f32::NEG_INFINITY),
    ] {
        assert_invalid(g().origin(bad).build(), "grid.origin", "finite");
        assert_invalid(g().velocity(bad).build(), "grid.velocity", "finite");
    }
    for bad in [
        Quat::from_xyzw(0.0, 0.0, 0.0, 2.0),
        Quat::from_xyzw(0.0, 0.0, 0.0, 0.0),
        Quat::from_xyzw(0.1, 0.2, 0.3, 0.4),
        Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0),
    ] {
        assert_invalid(
            g().rotation(bad).build(),
            "grid.rotation",
            "unit quaternion",
        );
    }
    // The peer scene's formulas give no substep below n = 3.
    for n in [0, 2, 9000] {
        assert_invalid(
            cloth_core::presets::peer_ball(n),
            "peer_ball n",
            "3 ..= 8192",
        );
    }
    // A size so large that positions would overflow f32 is caught by the length bound.
    assert_invalid(
        GridBuilder::new(3, 3).spacing(3e38, 3e38).build(),
        "grid.spacing.along_cols",
        "(0, 5000] m",
    );

    let err = g().pin_indices([3, 16]).build().unwrap_err();
    assert_eq!(
        err,
        ClothError::IndexOutOfRange {
            name: "grid.pins".into(),
            index: 16,
            len: 16
        }
    );
    let text = err.to_string();
    assert!(text.contains("grid.pins") && text.contains("16") && text.contains("0 ..= 15"));
}

// ---------------------------------------------------------------------------------------
// 5. Config, collider and API errors
// ---------------------------------------------------------------------------------------

fn small_cloth() -> cloth_core::Cloth {
    GridBuilder::new(4, 4)
        .origin(Vec3::new(0.0, 1.0, 0.0))
        .pin_corner(Corner::TopLeft)
        .build()
        .unwrap()
}

fn bad_configs() -> Vec<(SimConfig, &'static str, &'static str)> {
    let d = SimConfig::default;
    let mut v = Vec::new();
    for dt in [0.0, -0.01, f32::NAN, f32::INFINITY] {
        v.push((SimConfig { dt, ..d() }, "config.dt", "> 0"));
    }
    v.push((
        SimConfig { substeps: 0, ..d() },
        "config.substeps",
        "1 ..= 100000",
    ));
    v.push((
        SimConfig {
            substeps: 100_001,
            ..d()
        },
        "config.substeps",
        "1 ..= 100000",
    ));
    for outside in [0, 17] {
        let mut c = d();
        c.xpbd.chain_iterations = outside;
        v.push((c, "config.xpbd.chain_iterations", "1 ..= 16"));
        let mut c = d();
        c.xpbd.chain_rounds = outside;
        v.push((c, "config.xpbd.chain_rounds", "1 ..= 16"));
    }
    for outside in [0.0, -0.5, 2.0, f32::NAN, f32::INFINITY] {
        let mut c = d();
        c.xpbd.chain_relaxation = outside;
        v.push((
            c,
            "config.xpbd.chain_relaxation",
            "greater than 0 and less than 2",
        ));
    }
    for outside in [-0.01, 1.5, f32::NAN, f32::INFINITY] {
        let mut c = d();
        c.xpbd.structural_limit = Some(outside);
        v.push((c, "config.xpbd.structural_limit", "0 ..= 1"));
    }
    v.push((
        SimConfig {
            gravity: Vec3::new(0.0, f32::NAN, 0.0),
            ..d()
        },
        "config.gravity",
        "finite",
    ));
    v.push((
        SimConfig {
            damping: -0.1,
            ..d()
        },
        "config.damping",
        ">= 0",
    ));
    for kind in SpringKind::ALL {
        let mut c = d();
        let p = match kind {
            SpringKind::Warp => &mut c.material.warp,
            SpringKind::Weft => &mut c.material.weft,
            SpringKind::Shear => &mut c.material.shear,
            SpringKind::Bend => &mut c.material.bend,
        };
        *p = SpringParams::new(-1.0, 0.1);
        let name = match kind {
            SpringKind::Warp => "config.material.warp.stiffness",
            SpringKind::Weft => "config.material.weft.stiffness",
            SpringKind::Shear => "config.material.shear.stiffness",
            SpringKind::Bend => "config.material.bend.stiffness",
        };
        v.push((c, name, ">= 0"));
    }
    let mut c = d();
    c.material.bend.damping = f32::NAN;
    v.push((c, "config.material.bend.damping", ">= 0"));
    let mut c = d();
    c.air.density = -1.2;
    v.push((c, "config.air.density", ">= 0"));
    let mut c = d();
    c.air.drag_coefficient = f32::INFINITY;
    v.push((c, "config.air.drag_coefficient", ">= 0"));
    let mut c = d();
    c.air.lift_coefficient = -0.2;
    v.push((c, "config.air.lift_coefficient", ">= 0"));
    let mut c = d();
    c.air.wind = Vec3::new(f32::INFINITY, 0.0, 0.0);
    v.push((c, "config.air.wind", "finite"));
    let mut c = d();
    c.air.gust = Some(Gust {
        amplitude: 2.0,
        frequency: 0.5,
    });
    v.push((c, "config.air.gust.amplitude", "0 ..= 1"));
    let mut c = d();
    c.air.gust = Some(Gust {
        amplitude: 0.5,
        frequency: 0.0,
    });
    v.push((c, "config.air.gust.frequency", "> 0"));
    let mut c = d();
    c.limits.max_stretch_ratio = 1.0;
    v.push((c, "config.limits.max_stretch_ratio", "> 1"));
    let mut c = d();
    c.limits.max_speed = 0.0;
    v.push((c, "config.limits.max_speed", "> 0"));
    v
}

/// Every bad `SimConfig` field is an `InvalidArgument` naming that field and its range,
/// from `validate`, `Simulation::new` and `set_config`; a rejected `set_config` leaves the
/// configuration unchanged and the next step is bit-identical to a simulation that never
/// saw it.
#[test]
fn bad_config_values_are_rejected_and_leave_simulation_unchanged() {
    assert!(SimConfig::default().validate().is_ok());
    assert!(
        SimConfig {
            air: Air {
                gust: Some(Gust::default()),
                ..Air::default()
            },
            ..SimConfig::default()
        }
        .validate()
        .is_ok()
    );
    let mut sim = Simulation::new(small_cloth(), SimConfig::default()).unwrap();
    let mut reference = sim.clone();
    for (config, field, allowed) in bad_configs() {
        assert_invalid(config.validate(), field, allowed);
        assert_invalid(Simulation::new(small_cloth(), config), field, allowed);
        assert_invalid(sim.set_config(config), field, allowed);
        assert_eq!(*sim.config(), SimConfig::default(), "after bad {field}");
    }
    let a = sim.step().unwrap();
    let b = reference.step().unwrap();
    assert_eq!(a, b);
    assert_eq!(sim.particles(), reference.particles());
}

/// Bad colliders (zero/negative/NaN radius, zero or non-finite plane normal, negative
/// thickness, negative friction, non-finite centre, point or velocity) are rejected by
/// `add_collider` and `set_collider` with an `InvalidArgument` naming `colliders[i].field`;
/// the collider list is unchanged. A plane's normal is normalised when added.
#[test]
fn bad_colliders_are_rejected_and_leave_simulation_unchanged() {
    let mut sim = Simulation::new(small_cloth(), SimConfig::default()).unwrap();
    let good = Collider::sphere(Vec3::ZERO, 0.3);
    assert_eq!(sim.add_collider(good.clone()).unwrap(), 0);
    let cases = [
        (
            Collider::sphere(Vec3::ZERO, 0.0),
            "colliders[1].radius",
            "> 0",
        ),
        (
            Collider::sphere(Vec3::ZERO, -0.2),
            "colliders[1].radius",
            "> 0",
        ),
        (
            Collider::sphere(Vec3::ZERO, f32::NAN),
            "colliders[1].radius",
            "> 0",
        ),
        (
            Collider::sphere(Vec3::splat(f32::NAN), 1.0),
            "colliders[1].center",
            "finite",
        ),
        (
            Collider::plane(Vec3::ZERO, Vec3::ZERO),
            "colliders[1].normal",
            "non-zero",
        ),
        (
            Collider::plane(Vec3::ZERO, Vec3::new(0.0, f32::INFINITY, 0.0)),
            "colliders[1].normal",
            "finite",
        ),
        (
            Collider::plane(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::Y),
            "colliders[1].point",
            "finite",
        ),
        (
            good.clone().with_thickness(-0.01),
            "colliders[1].thickness",
            ">= 0",
        ),
        (
            good.clone().with_friction(Friction::new(-0.5, 0.4)),
            "colliders[1].friction.static_coefficient",
            ">= 0",
        ),
        (
            good.clone().with_friction(Friction::new(0.5, -0.4)),
            "colliders[1].friction.kinetic_coefficient",
            ">= 0",
        ),
        (
            good.clone().with_velocity(Vec3::new(0.0, f32::NAN, 0.0)),
            "colliders[1].velocity",
            "finite",
        ),
    ];
    for (collider, field, allowed) in cases {
        assert_invalid(sim.add_collider(collider.clone()), field, allowed);
        assert_eq!(sim.colliders(), std::slice::from_ref(&good));
        let field0 = field.replace("colliders[1]", "colliders[0]");
        assert_invalid(sim.set_collider(0, collider), &field0, allowed);
        assert_eq!(sim.colliders(), std::slice::from_ref(&good));
    }
    assert_invalid(
        sim.set_collider(1, good.clone()),
        "collider index",
        "0 ..= 0",
    );
    let i = sim
        .add_collider(Collider::plane(Vec3::ZERO, Vec3::new(0.0, 3.0, 4.0)))
        .unwrap();
    match &sim.colliders()[i].shape {
        cloth_core::Shape::Plane { normal, .. } => {
            assert!(normal.abs_diff_eq(Vec3::new(0.0, 0.6, 0.8), 1e-6));
        }
        other => panic!("expected a plane, got {other:?}"),
    }
}

/// A pin target further than `limits.max_speed · dt` from its particle (a pin faster than the
/// speed limit) is refused naming `set_pin_target.target` and the bound, and changes nothing;
/// one just within it is accepted. A step that a fast pin target makes fail says so in its
/// hint, naming the pinned particle and its speed (10 m in one 1/60 s step: 600 m/s).
#[test]
fn pin_targets_faster_than_the_speed_limit() {
    let mut sim = Simulation::new(small_cloth(), SimConfig::default()).unwrap();
    let pinned = (0..sim.particles().len())
        .find(|&i| sim.particles().is_pinned(i))
        .expect("a pinned corner");
    let at = sim.particles().position[pinned];
    let reach = sim.config().limits.max_speed * sim.config().dt;
    let before = sim.particles().clone();
    assert_invalid(
        sim.set_pin_target(pinned, at + Vec3::new(1.01 * reach, 0.0, 0.0)),
        "set_pin_target.target",
        "limits.max_speed",
    );
    assert_eq!(sim.particles(), &before);
    sim.step().expect("the refused target was not kept");
    assert_eq!(sim.particles().position[pinned], at);

    sim.set_pin_target(pinned, at + Vec3::new(0.99 * reach, 0.0, 0.0))
        .expect("within max_speed · dt");

    let mut sim = Simulation::new(small_cloth(), SimConfig::default()).unwrap();
    sim.set_pin_target(pinned, at + Vec3::new(10.0, 0.0, 0.0))
        .expect("10 m: within the speed limit");
    let Err(ClothError::Unstable { hint, .. }) = sim.step() else {
        panic!("a corner pulled 10 m in one step tears the cloth");
    };
    assert!(
        hint.contains("set_pin_target")
            && hint.contains(&format!("particle {pinned}"))
            && hint.contains("6.000e2 m/s"),
        "{hint}"
    );
}

/// Bad API arguments: out-of-range particle indices give `IndexOutOfRange` naming the
/// call; non-finite positions, velocities and pin targets give `InvalidArgument`;
/// `set_pin_target` on a free particle is refused. None of them changes the particles.
#[test]
fn bad_api_arguments_are_errors_and_change_nothing() {
    let mut sim = Simulation::new(small_cloth(), SimConfig::default()).unwrap();
    let before = sim.particles().clone();
    let n = before.len();
    let oor = |name: &str| ClothError::IndexOutOfRange {
        name: name.into(),
        index: n,
        len: n,
    };
    assert_eq!(sim.pin(n), Err(oor("pin")));
    assert_eq!(sim.unpin(n), Err(oor("unpin")));
    assert_eq!(sim.set_position(n, Vec3::ZERO), Err(oor("set_position")));
    assert_eq!(sim.set_velocity(n, Vec3::ZERO), Err(oor("set_velocity")));
    assert_eq!(
        sim.set_pin_target(n, Vec3::ZERO),
        Err(oor("set_pin_target"))
    );
    let text = oor("set_position").to_string();
    assert!(
        text.contains("set_position") && text.contains("0 ..= 15"),
        "{text}"
    );

    let nan = Vec3::new(f32::NAN, 0.0, 0.0);
    assert_invalid(sim.set_position(3, nan), "set_position.position", "finite");
    assert_invalid(
        sim.set_position(3, Vec3::splat(f32::INFINITY)),
        "set_position.position",
        "finite",
    );
    assert_invalid(sim.set_velocity(3, nan), "set_velocity.velocity", "finite");
    assert_invalid(
        sim.set_pin_target(0, nan),
        "set_pin_target.target",
        "finite",
    );
    // particle 5 is free
    assert!(!sim.particles().is_pinned(5));
    assert_invalid(
        sim.set_pin_target(5, Vec3::ZERO),
        "set_pin_target index",
        "a pinned particle",
    );
    assert_eq!(sim.particles(), &before);
}

// ---------------------------------------------------------------------------------------
// 6. Determinism
// ---------------------------------------------------------------------------------------

/// FNV-1a (64-bit) over the bits of every position component.
fn fnv1a_positions(x: &[Vec3]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in x {
        for c in p.to_array() {
            for byte in c.to_bits().to_le_bytes() {
                h ^= u64::from(byte);
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
    }
    h
}

/// A fabric given explicitly (not `Material::default()`), so that these tests do not change
/// when the defaults are retuned: structural 500 N/m, shear 100 N/m, bend 20 N/m, each with
/// a 0.1 N·s/m dashpot.
const FABRIC: Material = Material::isotropic(
    SpringParams::new(500.0, 0.1),
    SpringParams::new(100.0, 0.1),
    SpringParams::new(20.0, 0.1),
);

/// Every current parameter given explicitly (same reason as [`FABRIC`]), with enough
/// substeps for forward Euler (which gains energy every substep) to stay finite for a few
/// hundred steps. Fields added later take their defaults.
fn stable_config(integrator: Integrator) -> SimConfig {
    let forces = ForceSwitches {
        gravity: true,
        springs: true,
        dashpots: true,
        damping: true,
        air: true,
    };
    SimConfig {
        dt: 1.0 / 60.0,
        substeps: if integrator == Integrator::ForwardEuler {
            128
        } else {
            32
        },
        integrator,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        damping: 0.002,
        material: FABRIC,
        air: Air {
            density: 1.2,
            drag_coefficient: 1.0,
            lift_coefficient: 0.2,
            wind: Vec3::ZERO,
            gust: None,
        },
        forces,
        limits: StabilityLimits {
            max_stretch_ratio: 10.0,
            max_speed: 1000.0,
        },
        ..SimConfig::default()
    }
}

fn golden_scene(integrator: Integrator) -> Simulation {
    let cloth = GridBuilder::new(16, 16)
        .size(1.0, 1.0)
        .origin(Vec3::new(0.03, 0.5, -0.02))
        .build()
        .unwrap();
    let mut sim = Simulation::new(cloth, stable_config(integrator)).unwrap();
    sim.add_collider(Collider::sphere(Vec3::ZERO, 0.3).with_friction(Friction::new(0.8, 0.6)))
        .unwrap();
    sim.add_collider(Collider::plane(Vec3::new(0.0, -0.5, 0.0), Vec3::Y))
        .unwrap();
    sim
}

fn run_golden(integrator: Integrator) -> (u64, Vec<Vec3>) {
    let mut sim = golden_scene(integrator);
    for _ in 0..120 {
        sim.step().unwrap();
    }
    assert!(sim.stats().contacts > 0, "the scene must exercise contacts");
    let x = sim.particles().position.clone();
    (fnv1a_positions(&x), x)
}

/// Golden digests of the fixed scene (16×16 cloth dropped on a frictional sphere above a
/// ground plane, 120 steps). A change in these values means the arithmetic of the step
/// changed (operation order, a formula, a constant): it must be intentional, and then the
/// values are updated here. They are for x86_64 with the default target features (SSE2,
/// no FMA contraction).
// Updated on purpose when `forces::accumulate` went from three divisions per spring
// (l / |l|) to one reciprocal and three products (l · (1/|l|)), which the grid fast path
// shares; XPBD does not use that spring force and kept its digest. Updated on purpose when
// XPBD on a grid cloth went to the grid path (coloured Gauss–Seidel, `solver::grid_xpbd`),
// the default wherever a grid kernel runs; its reference path keeps the old digest
// (`XPBD_REFERENCE_GOLDEN`). Updated on purpose, every integrator's and XPBD's reference
// path's, when the air force went from twelve divisions per triangle to two (the normal and
// the flow direction by one reciprocal each, the thirds as products), in the reference and in
// the grid paths' air kernel alike. Updated on purpose, every integrator's, when the air
// force went to one square root and one division per triangle (`t = 1/√(|c|²·|r|²)`), in the
// reference and the grid paths' air kernel alike; XPBD's reference path kept its digest (its
// air terms' last bits are lost when added to the weight). Updated on purpose, XPBD's only,
// when the grid path's pair correction went from two divisions per spring (1/|l| and Δλ) to
// one (Δλ/|l|, applied along l); its reference path keeps its digest. Updated on purpose,
// implicit Euler's only, when its Coulomb friction moved into the solve (a sticking contact
// fixed at the collider's velocity, kinetic friction in the right-hand side) instead of a
// velocity filter after the solve, and its CG's stop gained a floor (one substep's gravity
// impulse); and again when its contacts that pull their particle in were released, with a
// second solve. Updated on purpose, every integrator's but XPBD's, when the spring force
// took its square root and its one division both from the squared length (1/|l| as
// |l|·(1/|l|²), the damping term along l times 1/|l|²) instead of the division after the
// square root, in the reference and every grid kernel alike. Updated on purpose, XPBD's and
// XPBD's reference path's, when its velocities became v + (x − x_pred)/h (the prediction's
// rounding of x_pred left out) instead of (x − x_prev)/h, in the reference and grid paths
// alike.
const GOLDEN: [(Integrator, u64); 5] = [
    (Integrator::ForwardEuler, 0xc306_2e0c_2963_1917),
    (Integrator::SymplecticEuler, 0xe742_c010_6175_7d07),
    (Integrator::Verlet, 0x7f30_5bee_53d1_42b2),
    (Integrator::ImplicitEuler, 0xbd4b_c9eb_7ca0_102f),
    (Integrator::Xpbd, 0xc3e8_ea09_0536_3aa3),
];

/// XPBD's digest on the reference path (storage-order Gauss–Seidel).
const XPBD_REFERENCE_GOLDEN: u64 = 0xa351_942e_16b0_cf3e;

/// Determinism of XPBD's reference path: its digest is unchanged by the grid path.
#[test]
fn golden_digest_of_the_xpbd_reference_path() {
    use cloth_core::simd::{self, Kernel};
    simd::set_kernel(Some(Kernel::Reference)).unwrap();
    let (h, _) = run_golden(Integrator::Xpbd);
    simd::set_kernel(None).unwrap();
    assert_eq!(h, XPBD_REFERENCE_GOLDEN, "{h:#018x}");
}

/// Determinism: two independent runs of the same scene give bit-identical positions, and
/// the FNV-1a digest of the position bits equals the golden value for each integrator.
#[test]
fn golden_digest_per_integrator() {
    let mut wrong = Vec::new();
    for integrator in Integrator::ALL {
        let (h1, x1) = run_golden(integrator);
        let (h2, x2) = run_golden(integrator);
        let bits = |x: &[Vec3]| -> Vec<u32> {
            x.iter()
                .flat_map(|p| p.to_array().map(f32::to_bits))
                .collect()
        };
        assert_eq!(bits(&x1), bits(&x2), "{integrator:?}: runs differ");
        assert_eq!(h1, h2);
        // Every integrator's digest is checked before failing, so that one run lists them all.
        match GOLDEN.iter().find(|(i, _)| *i == integrator) {
            Some(&(_, golden)) if golden == h1 => {}
            Some(_) => wrong.push(format!("({integrator:?}, {h1:#018x}) differs")),
            None => wrong.push(format!("({integrator:?}, {h1:#018x}) missing")),
        }
    }
    assert!(wrong.is_empty(), "golden digests: {}", wrong.join("; "));
}

// ---------------------------------------------------------------------------------------
// 7. Instability
// ---------------------------------------------------------------------------------------

/// A very stiff cloth (k = 1e6 N/m, particle masses ~1e-3 kg, so ω·h ≈ 500 ≫ 2 with one
/// substep of 1/60 s) under symplectic Euler blows up; the step that would leave a runaway
/// state returns `Unstable` naming the step, a particle and a hint about `substeps`, and
/// the simulation keeps the state from before that step bit for bit (positions,
/// velocities, time, step count, stats).
#[test]
fn instability_is_reported_and_state_restored() {
    let cloth = GridBuilder::new(8, 8)
        .size(0.5, 0.5)
        .origin(Vec3::new(0.0, 1.0, 0.0))
        .pin_corner(Corner::TopLeft)
        .build()
        .unwrap();
    let stiff = SpringParams::new(1e6, 0.0);
    let config = SimConfig {
        integrator: Integrator::SymplecticEuler,
        substeps: 1,
        dt: 1.0 / 60.0,
        material: Material::isotropic(stiff, stiff, stiff),
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config).unwrap();
    let mut failed = None;
    for _ in 0..10 {
        let x = sim.particles().position.clone();
        let v = sim.particles().velocity.clone();
        let (t, s, stats) = (sim.time(), sim.steps(), *sim.stats());
        match sim.step() {
            Ok(_) => {}
            Err(err) => {
                failed = Some((err, x, v, t, s, stats));
                break;
            }
        }
    }
    let (err, x, v, t, s, stats) = failed.expect("the stiff cloth must be reported unstable");
    assert!(s <= 5, "reported only at step {s}");
    let ClothError::Unstable {
        step,
        time,
        particle,
        ref reason,
        ref hint,
    } = err
    else {
        panic!("expected Unstable, got {err:?}");
    };
    assert_eq!(step, s);
    assert_eq!(time, t);
    assert!((particle as usize) < 64);
    assert!(!reason.is_empty());
    assert!(hint.contains("substeps"), "{hint}");
    let text = err.to_string();
    eprintln!("stiff cloth: {text}");
    assert!(text.contains(&format!("unstable at step {s}")), "{text}");
    assert!(text.contains(&format!("particle {particle}")), "{text}");
    assert!(text.contains("substeps"), "{text}");

    let p = sim.particles();
    assert!(p.position.iter().chain(&p.velocity).all(|q| q.is_finite()));
    let bits = |x: &[Vec3]| -> Vec<u32> {
        x.iter()
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .collect()
    };
    assert_eq!(bits(&p.position), bits(&x));
    assert_eq!(bits(&p.velocity), bits(&v));
    assert_eq!(sim.time(), t);
    assert_eq!(sim.steps(), s);
    assert_eq!(*sim.stats(), stats);
    // Stepping again fails the same way from the same state: nothing advanced.
    let again = sim.step().unwrap_err();
    assert_eq!(again, err);

    // A pin target set before a failed step survives it: after following the hint (more
    // substeps), the retried step takes the pin exactly to its target.
    let target = sim.particles().position[0] + Vec3::new(0.0, 0.01, 0.0);
    sim.set_pin_target(0, target).unwrap();
    assert!(matches!(sim.step(), Err(ClothError::Unstable { .. })));
    assert_eq!(bits(&sim.particles().position), bits(&x));
    let mut fixed = *sim.config();
    let limit = cloth_core::diagnostics::explicit_stability_limit(
        &fixed,
        sim.particles()
            .mass
            .iter()
            .copied()
            .fold(f32::INFINITY, f32::min),
    );
    fixed.substeps = (1.5 * fixed.dt / limit).ceil() as u32;
    sim.set_config(fixed).unwrap();
    sim.step()
        .expect("the retried step with enough substeps is stable");
    assert_eq!(sim.particles().position[0], target);
    assert_eq!(sim.steps(), s + 1);
}

/// When no allowed substep count is enough (a cloth of 10⁻⁹ kg/m² needs about 10⁶ substeps
/// of symplectic Euler per 1/60 s step; at most 100000 are allowed), the hint says so and
/// names what to change instead of asking for an impossible `substeps`.
#[test]
fn instability_hint_says_when_no_allowed_substeps_is_enough() {
    let cloth = GridBuilder::new(8, 8)
        .size(0.5, 0.5)
        .mass(Mass::ArealDensity(1e-9))
        .pin_corner(Corner::TopLeft)
        .build()
        .unwrap();
    let config = SimConfig {
        integrator: Integrator::SymplecticEuler,
        substeps: 1,
        dt: 1.0 / 60.0,
        ..SimConfig::default()
    };
    let min_mass = cloth
        .particles
        .mass
        .iter()
        .copied()
        .fold(f32::INFINITY, f32::min);
    let limit = cloth_core::diagnostics::explicit_stability_limit(&config, min_mass);
    assert!(
        config.dt / limit > 1e5,
        "the case needs more than 100000 substeps"
    );
    let mut sim = Simulation::new(cloth, config).unwrap();
    let err = (0..10)
        .find_map(|_| sim.step().err())
        .expect("the feather-light cloth must be reported unstable");
    let ClothError::Unstable { ref hint, .. } = err else {
        panic!("expected Unstable, got {err:?}");
    };
    assert!(hint.contains("no allowed `substeps` is enough"), "{hint}");
    assert!(hint.contains("at most 100000"), "{hint}");
    assert!(hint.contains("density") && hint.contains("xpbd"), "{hint}");
    assert!(!hint.contains("raise `substeps` to at least"), "{hint}");
}

/// A gravity that alone passes the speed limit (1000 m/s by default) within ten steps is
/// named as the cause, whatever the integrator, and no substep count is suggested: here
/// 10⁶ m/s² adds 1.7·10⁴ m/s per 1/60 s step, and the first step is reported unstable.
#[test]
fn instability_hint_names_an_extreme_gravity() {
    for integrator in [Integrator::SymplecticEuler, Integrator::Xpbd] {
        let cloth = GridBuilder::new(8, 8).size(0.5, 0.5).build().unwrap();
        let config = SimConfig {
            integrator,
            gravity: Vec3::new(0.0, -1e6, 0.0),
            ..SimConfig::default()
        };
        let mut sim = Simulation::new(cloth, config).unwrap();
        let err = sim.step().expect_err("past the speed limit in one step");
        let ClothError::Unstable { ref hint, .. } = err else {
            panic!("expected Unstable, got {err:?}");
        };
        assert!(hint.contains("gravity of 1.000e6 m/s²"), "{hint}");
        assert!(hint.contains("lower `forces.gravity`"), "{hint}");
        assert!(!hint.contains("substeps"), "{hint}");
    }
}

/// Forward Euler multiplies the energy of an undamped spring mode by 1 + (ωh)² every
/// substep, so an undamped cloth (no global damping, dashpots or air) must eventually be
/// reported `Unstable`, here within 600 steps (10 s), with the forward-Euler hint; the
/// state stays finite.
#[test]
fn forward_euler_undamped_eventually_unstable() {
    let cloth = GridBuilder::new(8, 8)
        .origin(Vec3::new(0.0, 1.0, 0.0))
        .pin_corner(Corner::TopLeft)
        .pin_corner(Corner::TopRight)
        .build()
        .unwrap();
    let mut config = SimConfig {
        integrator: Integrator::ForwardEuler,
        damping: 0.0,
        ..SimConfig::default()
    };
    config.forces.dashpots = false;
    config.forces.air = false;
    let mut sim = Simulation::new(cloth, config).unwrap();
    let mut failure = None;
    for _ in 0..600 {
        if let Err(e) = sim.step() {
            failure = Some(e);
            break;
        }
    }
    let err = failure.expect("forward Euler must blow up on an undamped cloth");
    let ClothError::Unstable { hint, step, .. } = &err else {
        panic!("expected Unstable, got {err:?}");
    };
    assert_eq!(*step, sim.steps());
    assert!(hint.contains("forward Euler"), "{hint}");
    let p = sim.particles();
    assert!(p.position.iter().chain(&p.velocity).all(|q| q.is_finite()));
    eprintln!("forward Euler unstable at step {step}");
}

// ---------------------------------------------------------------------------------------
// 8. Pins
// ---------------------------------------------------------------------------------------

/// `set_pin_target` moves a pinned particle to the target exactly (bit for bit) by the end
/// of the step, for every integrator, and the pin is at rest after the step; without a new
/// target it stays there.
#[test]
fn pin_target_is_reached_exactly() {
    for integrator in Integrator::ALL {
        let cloth = GridBuilder::new(6, 6)
            .orientation(Orientation::Vertical)
            .origin(Vec3::new(0.0, 1.0, 0.0))
            .pin_corner(Corner::TopLeft)
            .pin_corner(Corner::TopRight)
            .build()
            .unwrap();
        let mut sim = Simulation::new(cloth, stable_config(integrator)).unwrap();
        let start = sim.particles().position[0];
        for k in 1..=20 {
            let target = start + Vec3::new(0.013 * k as f32, 0.007 * k as f32, -0.011);
            sim.set_pin_target(0, target).unwrap();
            sim.step().unwrap();
            assert_eq!(sim.particles().position[0], target, "{integrator:?}");
            assert_eq!(sim.particles().velocity[0], Vec3::ZERO);
        }
        let rest = sim.particles().position[0];
        let other = sim.particles().position[5];
        sim.step().unwrap();
        assert_eq!(sim.particles().position[0], rest);
        assert_eq!(sim.particles().position[5], other);
    }
}

/// Pinning and unpinning between steps: `pin` sets inv_mass to 0 and stops the particle,
/// which then stays put exactly; `unpin` restores inv_mass = 1/mass (bit for bit) and the
/// particle falls again (it moves down under gravity within one step); an unpinned
/// particle forgets its pin target.
#[test]
fn pin_and_unpin_between_steps() {
    let cloth = GridBuilder::new(5, 5)
        .origin(Vec3::new(0.0, 1.0, 0.0))
        .build()
        .unwrap();
    let mut sim = Simulation::new(cloth, SimConfig::default()).unwrap();
    let mass = sim.particles().mass.clone();
    for _ in 0..5 {
        sim.step().unwrap();
    }
    let i = 12;
    sim.pin(i).unwrap();
    assert_eq!(sim.particles().inv_mass[i], 0.0);
    assert_eq!(sim.particles().velocity[i], Vec3::ZERO);
    assert_eq!(sim.particles().mass[i], mass[i]);
    let held = sim.particles().position[i];
    for _ in 0..10 {
        sim.step().unwrap();
        assert_eq!(sim.particles().position[i], held);
    }
    // the free neighbours hang below the pinned centre particle
    assert!(sim.particles().position[0].y < held.y);
    // set_velocity on a pinned particle is ignored
    sim.set_velocity(i, Vec3::new(1.0, 0.0, 0.0)).unwrap();
    assert_eq!(sim.particles().velocity[i], Vec3::ZERO);

    sim.set_pin_target(i, held + Vec3::Y).unwrap();
    sim.unpin(i).unwrap();
    assert_eq!(sim.particles().inv_mass[i], 1.0 / mass[i]);
    sim.step().unwrap();
    let y = sim.particles().position[i].y;
    assert!(
        y < held.y,
        "unpinned particle must fall, not follow the old target: {y}"
    );
    // pin it again, mid-air
    sim.pin(i).unwrap();
    let held = sim.particles().position[i];
    sim.step().unwrap();
    assert_eq!(sim.particles().position[i], held);
}

/// `restore` takes back a saved state bit for bit (and the next step from it is the same
/// step), and refuses a state that does not fit the simulation, naming the field, with
/// nothing changed: other counts, non-finite values, a negative time, or an inverse mass
/// that is neither 0 (pinned) nor the particle's own 1/mass.
#[test]
fn restore_takes_back_a_state_and_refuses_one_that_does_not_fit() {
    let build = || {
        let cloth = GridBuilder::new(6, 6)
            .size(0.5, 0.5)
            .pin_corner(Corner::TopLeft)
            .build()
            .unwrap();
        Simulation::new(cloth, SimConfig::default()).unwrap()
    };
    let bits = |x: &[Vec3]| -> Vec<u32> {
        x.iter()
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .collect()
    };
    let mut a = build();
    a.step().unwrap();
    let mut saved = a.state();
    // A second particle pinned in the saved state: restoring it pins it.
    saved.inv_mass[7] = 0.0;
    a.step().unwrap();
    let mut b = build();
    b.restore(&saved).unwrap();
    assert!(b.particles().is_pinned(7));
    assert_eq!(b.time(), saved.time);
    a.restore(&saved).unwrap();
    a.step().unwrap();
    b.step().unwrap();
    assert_eq!(bits(&a.particles().position), bits(&b.particles().position));

    let before = bits(&b.particles().position);
    let refused = |f: &dyn Fn(&mut cloth_core::SimState), field: &str, allowed: &str| {
        let mut s = saved.clone();
        f(&mut s);
        let mut sim = build();
        let x = bits(&sim.particles().position);
        assert_invalid(sim.restore(&s), field, allowed);
        assert_eq!(bits(&sim.particles().position), x, "{field}: state changed");
    };
    refused(
        &|s| s.inv_mass[5] = 1e30,
        "state.inv_mass[5]",
        "0 (pinned) or ",
    );
    refused(&|s| s.time = -5.0, "state.time", ">= 0");
    refused(&|s| s.time = f64::NAN, "state.time", ">= 0");
    refused(
        &|s| s.position[3][1] = f32::NAN,
        "state",
        "finite positions",
    );
    refused(
        &|s| {
            s.velocity.pop();
        },
        "state.velocity",
        "36 entries",
    );
    assert_eq!(bits(&b.particles().position), before);
}

/// Symplectic Euler on a damped oscillator (stiffness κ and damping γ per unit mass) is stable
/// only while h²κ + 2hγ < 4, so strong dashpots bound the substep below what the stiffness
/// alone allows (their c/m grows as 1/Δx² where √(k/m) grows as 1/Δx: the drape at 512²).
/// "auto" substeps take that bound: a small cloth with strong dashpots gets more substeps than
/// the stiffness-only estimate asks for and runs 60 steps stably, while the stiffness-only
/// count is reported `Unstable`, with the damped bound in its hint.
#[test]
fn auto_substeps_respect_the_dashpots_stability_bound() {
    let source = r#"
name = "damped"
[cloth]
resolution = [24, 24]
size = [1.0, 1.0]
origin = [0.0, 1.0, 0.0]
density = 0.2
[material]
warp = { stiffness = 400.0, damping = 2.0 }
weft = { stiffness = 400.0, damping = 2.0 }
shear = { stiffness = 80.0, damping = 1.0 }
bend = { stiffness = 10.0, damping = 0.5 }
[solver]
kind = "symplectic-euler"
dt = 0.016666668
substeps = "auto"
"#;
    let scene = cloth_core::scene::Scene::from_toml(source, "damped.toml").expect("scene");
    let mut sim = scene.build().expect("build");
    let min_mass = sim.particles().min_mass();
    let stiffness_only = cloth_core::presets::stable_substeps(sim.config(), min_mass);
    let damped = cloth_core::diagnostics::explicit_stability_limit_of(
        sim.config(),
        sim.topology(),
        sim.particles(),
    );
    let auto = sim.config().substeps;
    assert!(
        auto > stiffness_only,
        "the dashpots must bind here: auto {auto}, stiffness only {stiffness_only}"
    );
    assert!(
        sim.config().substep_dt() < damped,
        "auto substeps within the damped bound"
    );
    for _ in 0..60 {
        sim.step().expect("auto substeps are stable");
    }

    let mut fast = scene.build().expect("build");
    let mut config = *fast.config();
    config.substeps = stiffness_only;
    fast.set_config(config).unwrap();
    let err = (0..60)
        .find_map(|_| fast.step().err())
        .expect("the stiffness-only substep must be unstable with these dashpots");
    let ClothError::Unstable { ref hint, .. } = err else {
        panic!("expected Unstable, got {err:?}");
    };
    assert!(hint.contains(&format!("{damped:.3e}")), "{hint}");
}
