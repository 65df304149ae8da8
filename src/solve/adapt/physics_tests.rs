//! Tests of what #25 added to the loop: meshes that follow regions' sides, Neumann sides,
//! magnets, nonlinear iron by Newton, and forces by the weighted stress tensor.

use super::*;
use crate::geom::{Point, Rect, Vertex};
use crate::solve::tests::slope;
use crate::solve::{Boundary, Curve, MU_0, Region, Shape, Side};
use std::f64::consts::PI;
use std::sync::Arc;

/// Checks the mesh after every insertion.
struct Checked;

impl SolveObserver for Checked {}

impl Observer for Checked {
    fn inserted(&mut self, mesh: &Mesh, vertex: u32) {
        if let Err(e) = mesh.check_invariants() {
            panic!("after inserting vertex {vertex}: {e}");
        }
    }
}

// ---- Meshes that follow the regions ------------------------------------------------------------

/// u in the two-material slab: k = 1 left of x = 0.61, 10 right of it, u = 0 at x = 0 and 1
/// at x = 1; the flux k u' is the same on both sides.
fn slab(x: f64) -> f64 {
    let slope_left = 1.0 / (0.61 + 0.39 / 10.0);
    if x <= 0.61 { slope_left * x } else { slope_left * 0.61 + slope_left / 10.0 * (x - 0.61) }
}

fn slab_error(shape: Shape) -> f64 {
    let region = Region { k: Some(10.0), ..Region::new(shape) };
    let problem = Problem::new(Rect::unit()).with_g(|x, _| slab(x)).with_region(region);
    let a = adapt(&problem, None, &Settings::new(10_000), &mut ()).unwrap();
    assert!(a.stats.vertices >= 9_000 && a.stats.delaunay, "{:?}", (a.stats.vertices, a.stats.delaunay));
    assert!(a.stats.constrained_edges > 0);
    a.mesh.vertices().iter().map(|v| (v.z - slab(v.x)).abs()).fold(0.0, f64::max)
}

#[test]
fn a_slab_whose_interface_is_not_dyadic_is_solved_to_rounding_as_a_rectangle_and_as_a_polygon() {
    // Before the mesh followed the sides: 3.3e-3 of max|u| at 10^4 vertices.
    let rect = Rect::new(0.61, 1.0, 0.0, 1.0).unwrap();
    assert!(slab_error(Shape::Rect(rect)) < 1e-4);
    let polygon = rect.corners().to_vec();
    assert!(slab_error(Shape::polygon(polygon, Rect::unit()).unwrap()) < 1e-4);
}

#[test]
fn a_rotated_square_conductors_sides_are_chains_of_mesh_edges_through_every_round() {
    let (c, r) = (Point::new(0.5, 0.5), 0.2);
    let corners: Vec<Point> = (0..4)
        .map(|k| {
            let a = PI / 7.0 + k as f64 * PI / 2.0;
            Point::new(c.x + r * a.cos(), c.y + r * a.sin())
        })
        .collect();
    let region =
        Region { f: Some(1.0), ..Region::new(Shape::polygon(corners.clone(), Rect::unit()).unwrap()) };
    let problem = Problem::new(Rect::unit()).with_region(region);
    let a = adapt(&problem, None, &Settings::new(3_000), &mut Checked).unwrap();
    let mesh = &a.mesh;
    let (mut length, mut count) = (0.0, 0);
    for e in (0..mesh.num_halfedges() as u32).filter(|&e| mesh.is_constrained(e) && mesh.twin(e) > e) {
        let (p, q) = (mesh.point(mesh.origin(e)), mesh.point(mesh.dest(e)));
        // Both ends on one side of the square, to rounding.
        let on_one = (0..4).any(|k| {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            let off = |p: Point| ((b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)).abs();
            off(p) < 1e-12 && off(q) < 1e-12
        });
        assert!(on_one, "constrained edge {p:?}–{q:?} is off the square");
        length += p.distance_sq(q).sqrt();
        count += 1;
    }
    assert_eq!(count, a.stats.constrained_edges);
    assert!(count > 4, "the sides were never split");
    assert!((length - 8.0 * r * std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12, "perimeter {length}");
    assert!(a.stats.delaunay);
}

// ---- Neumann sides ----------------------------------------------------------------------------

#[test]
fn neumann_sides_leave_u_free_where_its_normal_derivative_vanishes() {
    // u = sin(πx) cos(πy) has ∂u/∂y = 0 at y = 0 and 1; g = 0 is right only at x = 0 and 1.
    let exact = |x: f64, y: f64| (PI * x).sin() * (PI * y).cos();
    let boundary = Boundary { bottom: Side::Neumann, top: Side::Neumann, ..Boundary::default() };
    let problem =
        Problem::new(Rect::unit()).with_f(move |x, y| 2.0 * PI * PI * exact(x, y)).with_boundary(boundary);
    let a = adapt(&problem, Some(&exact), &Settings::new(10_000), &mut ()).unwrap();
    let last = a.stats.history.last().unwrap();
    assert!(last.max_nodal_error.unwrap() < 2e-3, "{last:?}");
    // On the Neumann sides u is near ±sin(πx), not g = 0.
    let bottom = a.mesh.vertices().iter().filter(|v| v.y == 0.0).map(|v| v.z).fold(0.0, f64::max);
    assert!((bottom - 1.0).abs() < 2e-3, "max u on y = 0 is {bottom}");
    let (energy, _) = (a.stats.history.iter().filter(|s| s.vertices >= 500))
        .map(|s| ((s.vertices as f64, s.energy_error.unwrap()), ()))
        .unzip::<_, _, Vec<_>, Vec<_>>();
    let rate = slope(&energy);
    assert!((-0.6..-0.4).contains(&rate), "energy-norm slope {rate}");
}

// ---- Periodic sides ---------------------------------------------------------------------------

/// Runs −Δu = f on the unit square with the left–right pair `side`, u = 0 at y = 0 and 1, and
/// checks u against `exact` and every left vertex against its partner on the right.
fn periodic_run(side: Side, exact: fn(f64, f64) -> f64, f: fn(f64, f64) -> f64) {
    let boundary = Boundary { left: side, right: side, ..Boundary::default() };
    let problem = Problem::new(Rect::unit()).with_f(f).with_boundary(boundary);
    let a = adapt(&problem, Some(&exact), &Settings::new(8_000), &mut Checked).unwrap();
    assert!(a.stats.history.last().unwrap().max_nodal_error.unwrap() < 2e-3, "{:?}", a.stats.history.last());
    let sign = side.sign().unwrap();
    let vertices = a.mesh.vertices();
    let (left, right): (Vec<&Vertex>, Vec<&Vertex>) =
        vertices.iter().filter(|v| v.x == 0.0 || v.x == 1.0).partition(|v| v.x == 0.0);
    assert_eq!(left.len(), right.len(), "every vertex on one side has a partner");
    assert!(left.len() > 20);
    for l in left {
        let r = right.iter().find(|r| r.y == l.y).expect("a partner at the same y");
        assert_eq!(r.z, sign * l.z, "u at (1, {}) against (0, {})", r.y, l.y);
    }
    assert!(a.stats.delaunay);
}

#[test]
fn a_periodic_pair_matches_its_vertices_and_gives_the_periodic_solution() {
    // u = cos(2πx) sin(πy): the same value and slope at x = 0 and 1, not zero there.
    periodic_run(
        Side::Periodic,
        |x, y| (2.0 * PI * x).cos() * (PI * y).sin(),
        |x, y| 5.0 * PI * PI * (2.0 * PI * x).cos() * (PI * y).sin(),
    );
}

#[test]
fn an_antiperiodic_pair_gives_the_antiperiodic_solution() {
    // u = cos(πx) sin(πy): u(1, y) = −u(0, y).
    periodic_run(
        Side::Antiperiodic,
        |x, y| (PI * x).cos() * (PI * y).sin(),
        |x, y| 2.0 * PI * PI * (PI * x).cos() * (PI * y).sin(),
    );
}

// ---- Magnets ----------------------------------------------------------------------------------

#[test]
fn a_magnet_slab_has_the_flux_density_of_its_one_dimensional_solution() {
    // A magnet across the box, y in [0.4, 0.6], M = (M0, 0); A = 0 at y = 0 and 1, Neumann at
    // x = 0 and 1, so A = A(y) and H_x = A'/μ0 − M is one constant C with ∫ A' = 0:
    // C = −0.2 M0, B_x = μ0 (C + M) = 0.8 μ0 M0 inside and −0.2 μ0 M0 outside.
    let m0 = 8e5;
    let magnet = Rect::new(0.0, 1.0, 0.4, 0.6).unwrap();
    let region = Region { k: Some(1.0 / MU_0), source: Some([m0, 0.0]), ..Region::new(Shape::Rect(magnet)) };
    let boundary = Boundary { left: Side::Neumann, right: Side::Neumann, ..Boundary::default() };
    let problem =
        Problem::new(Rect::unit()).with_k(|_, _| 1.0 / MU_0).with_region(region).with_boundary(boundary);
    let a = adapt(&problem, None, &Settings::new(2_000), &mut ()).unwrap();
    let exact = |y: f64| {
        let (outside, inside) = (-0.2 * MU_0 * m0, 0.8 * MU_0 * m0);
        if y <= 0.4 {
            outside * y
        } else if y <= 0.6 {
            outside * 0.4 + inside * (y - 0.4)
        } else {
            outside * 0.4 + inside * 0.2 + outside * (y - 0.6)
        }
    };
    let scale = 0.2 * MU_0 * m0 * 0.4;
    for v in a.mesh.vertices() {
        assert!(
            (v.z - exact(v.y)).abs() < 1e-9 * scale,
            "A({}, {}) = {}, exact {}",
            v.x,
            v.y,
            v.z,
            exact(v.y)
        );
    }
    // Energy ½ ν |B − Br|², Br = μ0 M in the magnet: |B − Br| = 0.2 μ0 M0 everywhere.
    let expected = 0.5 / MU_0 * (0.2 * MU_0 * m0).powi(2);
    assert!((a.stats.energy - expected).abs() < 1e-9 * expected, "{} against {expected}", a.stats.energy);
    // H = −0.2 M0 x̂ on every triangle, magnet or air; μr = 1 in both.
    let result = a.clone().into_result(crate::solve::Physics::Magnetostatic);
    let (h, mu_r) = (result.field("H").unwrap(), result.field("mu_r").unwrap());
    for (h, &mu_r) in h.values.chunks_exact(2).zip(&mu_r.values) {
        let (hx, hy) = (h[0], h[1]);
        assert!(
            (hx + 0.2 * m0).abs() < 1e-6 * m0 && hy.abs() < 1e-6 * m0 && (mu_r - 1.0).abs() < 1e-12,
            "{hx} {hy} {mu_r}"
        );
    }
    // Coenergy ∫ B·H − energy: H = −0.2 M0 everywhere, B·H = −0.2 M0 B.
    let b_dot_h = -0.2 * m0 * (0.8 * (-0.2) + 0.2 * 0.8) * MU_0 * m0;
    assert!((a.stats.coenergy - (b_dot_h - expected)).abs() < 1e-9 * expected, "{}", a.stats.coenergy);
}

// ---- Nonlinear iron ---------------------------------------------------------------------------

/// ν(B) = ν0 + ν1 B², so H = ν0 B + ν1 B³.
#[derive(Debug)]
struct Cubic {
    nu0: f64,
    nu1: f64,
}

impl Curve for Cubic {
    fn h(&self, b: f64) -> (f64, f64) {
        (self.nu0 * b + self.nu1 * b * b * b, self.nu0 + 3.0 * self.nu1 * b * b)
    }

    fn energy(&self, b: f64) -> f64 {
        0.5 * self.nu0 * b * b + 0.25 * self.nu1 * b.powi(4)
    }
}

/// −∇·(ν(|∇u|) ∇u) = f on the unit square with u = sin(πx) sin(πy) and ν = 1 + 4|∇u|²:
/// strongly nonlinear (ν runs from 1 to 1 + 4π²), f by central differences of the flux.
fn manufactured() -> (Problem<'static>, impl Fn(f64, f64) -> f64 + Sync) {
    let curve = Cubic { nu0: 1.0, nu1: 4.0 };
    let exact = |x: f64, y: f64| (PI * x).sin() * (PI * y).sin();
    let flux = move |x: f64, y: f64| {
        let g = [PI * (PI * x).cos() * (PI * y).sin(), PI * (PI * x).sin() * (PI * y).cos()];
        let nu = 1.0 + 4.0 * (g[0] * g[0] + g[1] * g[1]);
        [nu * g[0], nu * g[1]]
    };
    let f = move |x: f64, y: f64| {
        let h = 1e-5;
        -((flux(x + h, y)[0] - flux(x - h, y)[0]) + (flux(x, y + h)[1] - flux(x, y - h)[1])) / (2.0 * h)
    };
    let region = Region { curve: Some(Arc::new(curve)), ..Region::new(Shape::Rect(Rect::unit())) };
    (Problem::new(Rect::unit()).with_f(f).with_region(region), exact)
}

#[test]
fn a_manufactured_nonlinear_problem_converges_at_the_optimal_rate_and_newton_quadratically() {
    let (problem, exact) = manufactured();
    let a = adapt(&problem, Some(&exact), &Settings::new(20_000), &mut Checked).unwrap();
    assert_eq!(a.stats.stop, Stop::Mesh(StopReason::MaxVertices));
    let energy: Vec<(f64, f64)> = (a.stats.history.iter().filter(|s| s.vertices >= 500))
        .map(|s| (s.vertices as f64, s.energy_error.unwrap()))
        .collect();
    let rate = slope(&energy);
    assert!((-0.6..-0.4).contains(&rate), "energy-norm slope {rate}: {energy:?}");
    for step in &a.stats.history {
        assert!(step.newton_residual.unwrap() <= crate::solve::NEWTON_TOLERANCE, "{step:?}");
        // Started from the last solution interpolated, a round needs few steps.
        assert!(step.newton_iterations.unwrap() <= 12, "{step:?}");
    }

    // From u = 0 on one mesh, the residual falls quadratically once it is small.
    let mesh = &a.mesh;
    let triangles: Vec<[u32; 3]> = mesh.triangles().collect();
    let solution = crate::solve::solve(&problem, mesh.vertices(), &triangles).unwrap();
    let r = solution.newton.unwrap().residuals;
    // Above the floor rounding sets (the condition number of 10^4 unknowns times ε).
    let tail: Vec<&[f64]> = r.windows(2).filter(|w| w[0] < 1e-1 && w[1] > 1e-10).collect();
    assert!(!tail.is_empty(), "{r:?}");
    for w in tail {
        assert!(w[1] <= 10.0 * w[0] * w[0], "not quadratic: {r:?}");
    }
}

/// H = B + B³, whose slope turns wrong (a thousandth of the truth) after `limit` calls:
/// Newton with that Jacobian crawls, so the round it happens in cannot converge.
#[derive(Debug)]
struct Fickle {
    calls: std::sync::atomic::AtomicUsize,
    limit: usize,
}

impl Curve for Fickle {
    fn h(&self, b: f64) -> (f64, f64) {
        let calls = self.calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let slope = 1.0 + 3.0 * b * b;
        (b + b * b * b, if calls < self.limit { slope } else { 1e-3 * slope })
    }

    fn energy(&self, b: f64) -> f64 {
        0.5 * b * b + 0.25 * b.powi(4)
    }
}

#[test]
fn newton_that_cannot_converge_stops_the_run_with_the_last_converged_round() {
    let curve = Fickle { calls: 0.into(), limit: 40_000 };
    let region = Region { curve: Some(Arc::new(curve)), ..Region::new(Shape::Rect(Rect::unit())) };
    let problem = Problem::new(Rect::unit()).with_f(|x, _| 10.0 * (1.0 + x)).with_region(region);
    let a = adapt(&problem, None, &Settings::new(20_000), &mut ()).unwrap();
    assert_eq!(a.stats.stop, Stop::NotConverged);
    assert!(a.stats.solves >= 2, "{:?}", a.stats.history);
    for step in &a.stats.history {
        assert!(step.newton_residual.unwrap() <= crate::solve::NEWTON_TOLERANCE, "{step:?}");
    }
    // The mesh the failed round refined carries the last converged solution, interpolated.
    assert!(a.stats.vertices > a.stats.history.last().unwrap().vertices);
    assert!(a.mesh.vertices().iter().all(|v| v.z.is_finite()));
    assert!(a.stats.vertices < 20_000);
}

// ---- Forces -----------------------------------------------------------------------------------

/// A square of side `side` centred at (x, y) carrying `current` amperes.
fn conductor(x: f64, y: f64, side: f64, current: f64) -> Region {
    let h = side / 2.0;
    let rect = Rect::new(x - h, x + h, y - h, y + h).unwrap();
    Region {
        k: Some(1.0 / MU_0),
        f: Some(current / (side * side)),
        source: Some([0.0; 2]),
        ..Region::new(Shape::Rect(rect))
    }
}

#[test]
fn two_long_parallel_conductors_attract_with_mu0_i1_i2_over_2_pi_d() {
    let (d, i) = (0.05, 100.0);
    let problem = Problem::new(Rect::new(-1.0, 1.0, -1.0, 1.0).unwrap())
        .with_k(|_, _| 1.0 / MU_0)
        .with_region(conductor(-d / 2.0, 0.0, 0.01, i))
        .with_region(conductor(d / 2.0, 0.0, 0.01, i));
    let a = adapt(&problem, None, &Settings::new(30_000), &mut ()).unwrap();
    let expected = MU_0 * i * i / (2.0 * PI * d);
    let [left, right] = [&a.stats.regions[0], &a.stats.regions[1]];
    assert!((left.current - i).abs() < 1e-9 * i);
    // Attraction: the left one is pulled right, the right one left.
    assert!((left.force[0] - expected).abs() < 1e-2 * expected, "{:?} against {expected}", left.force);
    assert!((right.force[0] + expected).abs() < 1e-2 * expected, "{:?} against {expected}", right.force);
    assert!(left.force[1].abs() < 1e-2 * expected && right.force[1].abs() < 1e-2 * expected);
    // Antiparallel currents repel.
    let problem = Problem::new(Rect::new(-1.0, 1.0, -1.0, 1.0).unwrap())
        .with_k(|_, _| 1.0 / MU_0)
        .with_region(conductor(-d / 2.0, 0.0, 0.01, i))
        .with_region(conductor(d / 2.0, 0.0, 0.01, -i));
    let a = adapt(&problem, None, &Settings::new(30_000), &mut ()).unwrap();
    assert!((a.stats.regions[0].force[0] + expected).abs() < 1e-2 * expected, "{:?}", a.stats.regions[0]);
}

#[test]
fn a_conductor_and_an_iron_block_feel_equal_and_opposite_forces() {
    let iron_rect = Rect::new(0.02, 0.06, -0.03, 0.03).unwrap();
    let iron = Region {
        k: Some(1.0 / (1000.0 * MU_0)),
        f: Some(0.0),
        source: Some([0.0; 2]),
        ..Region::new(Shape::Rect(iron_rect))
    };
    let problem = Problem::new(Rect::new(-1.0, 1.0, -1.0, 1.0).unwrap())
        .with_k(|_, _| 1.0 / MU_0)
        .with_region(conductor(-0.01, 0.005, 0.01, 500.0))
        .with_region(iron);
    let a = adapt(&problem, None, &Settings::new(30_000), &mut ()).unwrap();
    let [wire, block] = [a.stats.regions[0].force, a.stats.regions[1].force];
    // The iron attracts the wire: the wire is pulled toward +x, the block toward −x.
    assert!(wire[0] > 0.0 && block[0] < 0.0, "{wire:?} {block:?}");
    let scale = wire[0].hypot(wire[1]);
    assert!(
        (wire[0] + block[0]).abs() < 1e-2 * scale && (wire[1] + block[1]).abs() < 1e-2 * scale,
        "{wire:?} {block:?}"
    );
    // Torque about the origin balances too.
    let [tw, tb] = [a.stats.regions[0].torque, a.stats.regions[1].torque];
    assert!((tw + tb).abs() < 2e-2 * tw.abs().max(tb.abs()) + 1e-2 * scale * 0.01, "{tw} {tb}");
}

#[test]
fn a_b_h_curve_through_the_spec_saturates_iron_so_more_current_gains_less_force() {
    // The same conductor beside a block of steel at 100 A (B of millitesla, on the curve's
    // initial slope) and 1 MA (tesla in the iron, saturated): the force grows by far less
    // than the 10^8 a linear block would give.
    let steel = Arc::new(
        crate::solve::BhCurve::new(&[[0.0, 0.0], [100.0, 0.6], [300.0, 1.1], [1000.0, 1.45], [10000.0, 1.8]])
            .unwrap(),
    );
    let force = |current: f64| {
        let block = Rect::new(0.02, 0.06, -0.03, 0.03).unwrap();
        let iron = Region {
            curve: Some(steel.clone()),
            f: Some(0.0),
            source: Some([0.0; 2]),
            ..Region::new(Shape::Rect(block))
        };
        let problem = Problem::new(Rect::new(-0.5, 0.5, -0.5, 0.5).unwrap())
            .with_k(|_, _| 1.0 / MU_0)
            .with_region(conductor(-0.01, 0.0, 0.01, current))
            .with_region(iron);
        let a = adapt(&problem, None, &Settings::new(8_000), &mut ()).unwrap();
        assert!(a.stats.history.iter().all(|s| s.newton_iterations.is_some()));
        a.stats.regions[0].force[0]
    };
    let (low, high) = (force(100.0), force(1e6));
    assert!(low > 0.0 && high > 0.0);
    assert!(high / low < 0.5e8, "force ratio {} for 10^4 × the current", high / low);
}
