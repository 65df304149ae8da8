//! Circuits: flux linkage and the apparent and incremental inductances against exact answers
//! and against finite differences of the flux linkage.

use super::*;
use crate::geom::{Point, Rect};
use crate::solve::coefficients::TriangleCoefficients;
use crate::solve::element::Element;
use crate::solve::{BhCurve, Circuit, Coil, MU_0, Region, Shape, solve};
use std::f64::consts::PI;
use std::sync::Arc;

/// A region of `shape` holding `turns` turns of circuit 0, which carries `current`.
fn coil(shape: Shape, turns: f64, current: f64) -> Region {
    let f = current * turns / shape.area();
    Region {
        k: Some(1.0 / MU_0),
        f: Some(f),
        source: Some([0.0; 2]),
        coil: Some(Coil { circuit: 0, turns }),
        ..Region::new(shape)
    }
}

/// A regular `n`-gon of radius `r` about (x, y).
fn disc(x: f64, y: f64, r: f64, n: usize, domain: Rect) -> Shape {
    let corners = (0..n).map(|k| {
        let t = 2.0 * PI * k as f64 / n as f64;
        Point::new(x + r * t.cos(), y + r * t.sin())
    });
    Shape::polygon(corners.collect(), domain).unwrap()
}

/// Air in `domain`, and circuit `name` carrying `current` through `coils`, each with its
/// signed turns.
fn in_air(
    domain: Rect,
    name: &str,
    current: f64,
    coils: impl IntoIterator<Item = (Shape, f64)>,
) -> Problem<'static> {
    let problem =
        Problem::new(domain).with_k(|_, _| 1.0 / MU_0).with_circuit(Circuit { name: name.into(), current });
    coils.into_iter().fold(problem, |p, (shape, turns)| p.with_region(coil(shape, turns, current)))
}

/// Round wires of radius `a` (64-gons), centres `d` apart on the x axis, carrying ±`current`
/// as circuit "line".
fn two_wire(domain: Rect, a: f64, d: f64, current: f64) -> Problem<'static> {
    let wires = [(-d / 2.0, 1.0), (d / 2.0, -1.0)].map(|(x, turns)| (disc(x, 0.0, a, 64, domain), turns));
    in_air(domain, "line", current, wires)
}

/// The two-wire line's inductance per metre at direct current: μ0/π · ln(d / a) outside the
/// wires (each a line current at its centre, seen from outside) plus μ0/8π inside each.
/// (acosh(d / 2a) is for currents pushed to the surfaces.)
fn two_wire_inductance(a: f64, d: f64) -> f64 {
    MU_0 / PI * (d / a).ln() + 2.0 * MU_0 / (8.0 * PI)
}

/// A ring of round wire of radius `a` (a 48-gon) on a circle of `big_r` about the axis,
/// carrying `current` as circuit "ring".
fn ring(domain: Rect, a: f64, big_r: f64, current: f64) -> Problem<'static> {
    in_air(domain, "ring", current, [(disc(big_r, 0.0, a, 48, domain), 1.0)])
        .with_geometry(crate::result::Geometry::Axisymmetric)
}

/// A thin ring's inductance, μ0 R (ln(8R/a) − 7/4), to O((a/R)²).
fn ring_inductance(a: f64, big_r: f64) -> f64 {
    MU_0 * big_r * ((8.0 * big_r / a).ln() - 1.75)
}

#[test]
fn a_two_wire_line_has_the_inductance_of_its_formula_and_both_agree_with_the_energy() {
    // Round wires of radius a, centres d apart, carrying ±I spread evenly (direct current).
    let (a, d, current) = (0.002, 0.02, 10.0);
    let domain = Rect::new(-0.4, 0.4, -0.4, 0.4).unwrap();
    let run = adapt(&two_wire(domain, a, d, current), None, &Settings::new(20_000), &mut ()).unwrap();
    let line = run.stats.circuits["line"];
    let exact = two_wire_inductance(a, d);
    let apparent = line.inductance.unwrap();
    assert!((apparent - exact).abs() < 2e-3 * exact, "{apparent} against {exact}");
    // Linear and without magnets: λ/I = dλ/dI = 2W/I².
    let incremental = line.incremental_inductance;
    assert!((incremental - apparent).abs() < 1e-9 * apparent, "{incremental} against {apparent}");
    let by_energy = 2.0 * run.stats.energy / (current * current);
    assert!((by_energy - apparent).abs() < 1e-9 * apparent, "{by_energy} against {apparent}");
    assert_eq!(line.current, current);
    assert!((line.flux_linkage - apparent * current).abs() < 1e-12);
}

#[test]
fn the_incremental_inductance_of_saturated_iron_is_the_derivative_of_the_flux_linkage() {
    // A coil around a steel bar, driven into saturation: dλ/dI from the tangent system must
    // match (λ(I + δ) − λ(I − δ)) / 2δ on the same mesh, and lie below λ/I.
    let steel = Arc::new(
        BhCurve::new(&[[0.0, 0.0], [100.0, 0.6], [300.0, 1.1], [1000.0, 1.45], [10000.0, 1.8]]).unwrap(),
    );
    let domain = Rect::new(-0.2, 0.2, -0.2, 0.2).unwrap();
    let problem = |current: f64| {
        let bar = Region {
            curve: Some(steel.clone()),
            f: Some(0.0),
            source: Some([0.0; 2]),
            ..Region::new(Shape::Rect(Rect::new(-0.01, 0.01, -0.05, 0.05).unwrap()))
        };
        let side = |x0: f64, turns: f64| {
            coil(Shape::Rect(Rect::new(x0, x0 + 0.01, -0.03, 0.03).unwrap()), turns, current)
        };
        Problem::new(domain)
            .with_k(|_, _| 1.0 / MU_0)
            .with_circuit(Circuit { name: "coil".into(), current })
            .with_region(bar)
            .with_region(side(0.012, 100.0))
            .with_region(side(-0.022, -100.0))
    };
    let current = 2000.0;
    let run = adapt(&problem(current), None, &Settings::new(4_000), &mut ()).unwrap();
    let points: Vec<Point> = run.mesh.vertices().iter().map(|v| v.point()).collect();
    let triangles: Vec<[u32; 3]> = run.mesh.triangles().collect();
    let at = |current: f64| {
        let problem = problem(current);
        let solution = solve(&problem, &points, &triangles).unwrap();
        let elements: Vec<Element> =
            (triangles.iter().enumerate()).map(|(t, &tri)| Element::new(&points, tri, t).unwrap()).collect();
        let coefficients: Vec<_> = (elements.iter().enumerate())
            .map(|(t, e)| TriangleCoefficients::of(&problem, e, t).unwrap())
            .collect();
        let circuits =
            super::circuits::measure(&problem, &points, &solution.u, &triangles, &elements, &coefficients);
        circuits.unwrap()["coil"]
    };
    let here = at(current);
    let delta = 1e-3 * current;
    let difference = (at(current + delta).flux_linkage - at(current - delta).flux_linkage) / (2.0 * delta);
    let incremental = here.incremental_inductance;
    assert!((incremental - difference).abs() < 1e-4 * difference, "{incremental} against {difference}");
    let apparent = here.inductance.unwrap();
    assert!(incremental < 0.9 * apparent, "saturated: dλ/dI {incremental} against λ/I {apparent}");
    // The loop's own figure is the same one, up to where its Newton started.
    let own = run.stats.circuits["coil"];
    assert!((own.incremental_inductance - incremental).abs() < 1e-9 * incremental, "{own:?} {here:?}");
}

/// The complete elliptic integrals K(m) and E(m), m = k², by the arithmetic-geometric mean.
fn elliptic(m: f64) -> (f64, f64) {
    let (mut a, mut b, mut sum, mut power) = (1.0, (1.0 - m).sqrt(), m / 2.0, 0.5);
    // Quadratic convergence: a handful of steps reach rounding, where a and b may stay an ulp apart.
    for _ in 0..40 {
        let (next_a, next_b) = ((a + b) / 2.0, (a * b).sqrt());
        power *= 2.0;
        sum += power * ((a - b) / 2.0).powi(2);
        (a, b) = (next_a, next_b);
    }
    let k = PI / (2.0 * a);
    (k, k * (1.0 - sum))
}

/// A_φ at (r, z) of a thin loop of radius `big_r` at z = 0 carrying `current` (Biot–Savart).
fn loop_potential(big_r: f64, current: f64, r: f64, z: f64) -> f64 {
    let m = 4.0 * big_r * r / ((big_r + r).powi(2) + z * z);
    let (k, e) = elliptic(m);
    MU_0 * current / (PI * m.sqrt()) * (big_r / r).sqrt() * ((1.0 - m / 2.0) * k - e)
}

#[test]
fn a_current_loop_turned_about_the_axis_has_the_field_of_biot_savart_and_a_rings_inductance() {
    // A ring of round wire, radius a = 1 mm, on a circle of R = 50 mm about the axis, 1 A,
    // in a box ten times R with A = 0 on its walls. Away from the wire A_φ is the thin loop's
    // (elliptic integrals), near the axis A_φ = r B_z(0, z) / 2 with B_z = μ0 I R² / 2(R² + z²)^{3/2};
    // the ring's inductance is μ0 R (ln(8R/a) − 7/4) to O((a/R)²).
    let (a, big_r, current) = (0.001, 0.05, 1.0);
    let domain = Rect::new(0.0, 0.5, -0.5, 0.5).unwrap();
    let run = adapt(&ring(domain, a, big_r, current), None, &Settings::new(20_000), &mut ()).unwrap();
    // A_φ = 0 on the axis; elsewhere within the box's reach, Biot–Savart's.
    assert!(run.mesh.vertices().iter().filter(|v| v.x == 0.0).all(|v| v.z == 0.0));
    let peak = loop_potential(big_r, current, big_r - 5.0 * a, 0.0);
    let mut checked = 0;
    for v in run.mesh.vertices() {
        let far = (v.x - big_r).hypot(v.y) > 5.0 * a;
        if v.x > 0.0 && v.x < 0.15 && v.y.abs() < 0.15 && far {
            let exact = loop_potential(big_r, current, v.x, v.y);
            assert!((v.z - exact).abs() < 1e-2 * peak, "A at ({}, {}): {} against {exact}", v.x, v.y, v.z);
            checked += 1;
        }
    }
    assert!(checked > 1000, "{checked} vertices checked");
    // On the axis the field is B_z = 2 A / r of the vertices nearest it.
    let near_axis = run.mesh.vertices().iter().filter(|v| v.x > 0.0 && v.x < 0.005 && v.y.abs() < 0.1);
    for v in near_axis {
        let exact = MU_0 * current * big_r * big_r / (2.0 * (big_r * big_r + v.y * v.y).powf(1.5));
        let bz = 2.0 * v.z / v.x;
        assert!((bz - exact).abs() < 3e-2 * exact, "B_z at z = {}: {bz} against {exact}", v.y);
    }
    let ring = run.stats.circuits["ring"];
    // Per radian: the whole turn is 2π times.
    let inductance = 2.0 * PI * ring.inductance.unwrap();
    let exact = ring_inductance(a, big_r);
    assert!((inductance - exact).abs() < 1e-2 * exact, "{inductance} against {exact}");
    let by_energy = 2.0 * run.stats.energy / (current * current);
    assert!((ring.inductance.unwrap() - by_energy).abs() < 1e-9 * by_energy);
    assert!((ring.incremental_inductance - by_energy).abs() < 1e-9 * by_energy);
    // Turned about the axis, the ring feels no net pull.
    assert_eq!(run.stats.regions[0].force[0], 0.0);
}

/// Every side open.
fn open() -> crate::solve::Boundary {
    use crate::solve::Side::Open;
    crate::solve::Boundary { left: Open, right: Open, bottom: Open, top: Open }
}

#[test]
fn a_wire_in_open_space_needs_a_box_of_only_a_few_radii() {
    // A round wire of radius a carrying I, alone: outside it A = −μ0 I/2π · ln(ρ/ρ₀) (the open
    // sides' gauge: ρ₀ is half the box's diagonal) and B = μ0 I / 2πρ, in a box 3a wide.
    let (a, current) = (0.001, 10.0);
    let domain = Rect::new(-0.003, 0.003, -0.003, 0.003).unwrap();
    let problem =
        in_air(domain, "wire", current, [(disc(0.0, 0.0, a, 64, domain), 1.0)]).with_boundary(open());
    let run = adapt(&problem, None, &Settings::new(10_000), &mut ()).unwrap();
    let rho_0 = domain.diagonal() / 2.0;
    let exact = |rho: f64| -MU_0 * current / (2.0 * PI) * (rho / rho_0).ln();
    let scale = exact(a).abs();
    let outside = run.mesh.vertices().iter().filter(|v| v.x.hypot(v.y) > 1.05 * a);
    let worst = outside.map(|v| (v.z - exact(v.x.hypot(v.y))).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-2 * scale, "A off by {worst} of {scale}");
    // B at 2a, from the triangle there.
    let [bx, by] = flux_density_at(&run, Point::new(0.002, 1e-7));
    let b = bx.hypot(by);
    let expected = MU_0 * current / (2.0 * PI * 0.002);
    assert!((b - expected).abs() < 2e-2 * expected, "|B| {b} against {expected}");
}

#[test]
fn a_two_wire_line_and_a_loop_in_small_open_boxes_keep_their_far_fields() {
    // The line of the first test in a box only 3d wide: its inductance within 1%.
    let (a, d, current) = (0.002, 0.02, 10.0);
    let domain = Rect::new(-0.06, 0.06, -0.06, 0.06).unwrap();
    let line = two_wire(domain, a, d, current).with_boundary(open());
    let run = adapt(&line, None, &Settings::new(20_000), &mut ()).unwrap();
    let exact = two_wire_inductance(a, d);
    let l = run.stats.circuits["line"].inductance.unwrap();
    assert!((l - exact).abs() < 1e-2 * exact, "{l} against {exact}");
    // The loop of R = 50 mm in a box reaching only 2R: inside 1.5R, where the device is,
    // A is Biot–Savart's within 4% of its peak, where A = 0 walls at the same place miss it by
    // more than 10%; the ring's inductance within 2%.
    let (a, big_r, current) = (0.001, 0.05, 1.0);
    let domain = Rect::new(0.0, 0.1, -0.1, 0.1).unwrap();
    let worst = |boundary: crate::solve::Boundary| {
        let ring = ring(domain, a, big_r, current).with_boundary(boundary);
        let run = adapt(&ring, None, &Settings::new(20_000), &mut ()).unwrap();
        let peak = loop_potential(big_r, current, big_r - 5.0 * a, 0.0);
        let near =
            |v: &&crate::geom::Vertex| v.x.hypot(v.y) < 1.5 * big_r && (v.x - big_r).hypot(v.y) > 5.0 * a;
        let errors = run.mesh.vertices().iter().filter(|v| v.x > 0.0).filter(near);
        let worst =
            errors.map(|v| (v.z - loop_potential(big_r, current, v.x, v.y)).abs()).fold(0.0, f64::max);
        (worst / peak, 2.0 * PI * run.stats.circuits["ring"].inductance.unwrap())
    };
    let (open_error, inductance) =
        worst(crate::solve::Boundary { left: crate::solve::Side::Dirichlet, ..open() });
    let (closed_error, _) = worst(crate::solve::Boundary::default());
    assert!(open_error < 0.04 && closed_error > 0.1, "open {open_error}, A = 0 walls {closed_error}");
    let exact = ring_inductance(a, big_r);
    assert!((inductance - exact).abs() < 2e-2 * exact, "{inductance} against {exact}");
}

/// B at `p` on a finished run's mesh: the flux density of the triangle that holds it.
fn flux_density_at(run: &Adapted, p: Point) -> [f64; 2] {
    let points: Vec<Point> = run.mesh.vertices().iter().map(|v| v.point()).collect();
    for (t, tri) in run.mesh.triangles().enumerate() {
        let e = Element::in_geometry(run.geometry, &points, tri, t).unwrap();
        if e.hats(p).iter().all(|&l| l >= 0.0) {
            let g = e.field(tri.map(|v| run.mesh.vertex(v).z));
            return [g[1], -g[0]];
        }
    }
    panic!("no triangle holds {p:?}")
}

/// `problem` turned about the axis, open on the three sides off it.
fn round_in_open_space(problem: Problem<'static>) -> Problem<'static> {
    problem
        .with_geometry(crate::result::Geometry::Axisymmetric)
        .with_boundary(crate::solve::Boundary { left: crate::solve::Side::Dirichlet, ..open() })
}

/// B_z on the axis of a thick solenoid, r from `a1` to `a2` and z from −`b` to `b`, carrying
/// the current density `j` around it: Biot–Savart integrated over the winding.
fn solenoid_axial_field(a1: f64, a2: f64, b: f64, j: f64, z: f64) -> f64 {
    let end = |x: f64| x * ((a2 + a2.hypot(x)) / (a1 + a1.hypot(x))).ln();
    MU_0 * j / 2.0 * (end(z + b) - end(z - b))
}

#[test]
fn a_finite_solenoid_in_an_open_box_has_biot_savarts_field_on_its_axis() {
    // 100 turns at 1 A on r ∈ [10, 12] mm, z ∈ [−20, 20] mm, in an open box of 80 × 200 mm:
    // B_z on the axis (the triangle at r = 0.1 mm, as /evaluate reads it) inside, at the end and
    // past it, within 1% of the centre's field. The triangles along the axis are the coarse
    // ones (the field there is nearly uniform): 2·10⁴ vertices miss z = 10 mm by 1.3%.
    let (a1, a2, b, turns, current) = (0.010, 0.012, 0.020, 100.0, 1.0);
    let domain = Rect::new(0.0, 0.08, -0.1, 0.1).unwrap();
    let winding = Shape::Rect(Rect::new(a1, a2, -b, b).unwrap());
    let problem = round_in_open_space(in_air(domain, "coil", current, [(winding, turns)]));
    let run = adapt(&problem, None, &Settings::new(40_000), &mut ()).unwrap();
    let j = turns * current / ((a2 - a1) * 2.0 * b);
    let centre = solenoid_axial_field(a1, a2, b, j, 0.0);
    for z in [0.0, 0.01, 0.02, 0.03] {
        let [br, bz] = flux_density_at(&run, Point::new(1e-4, z));
        let exact = solenoid_axial_field(a1, a2, b, j, z);
        assert!((bz - exact).abs() < 1e-2 * centre, "B_z at z = {z}: {bz} against {exact}");
        assert!(br.abs() < 1e-2 * centre, "B_r at z = {z}: {br}");
    }
}

/// The attraction between two coaxial filament loops of radii `r1`, `r2`, `z` apart, each
/// carrying 1 A: ∂M/∂z of Maxwell's mutual inductance, by elliptic integrals.
fn loop_attraction(r1: f64, r2: f64, z: f64) -> f64 {
    let m = 4.0 * r1 * r2 / ((r1 + r2).powi(2) + z * z);
    let (k, e) = elliptic(m);
    let e_factor = (r1 * r1 + r2 * r2 + z * z) / ((r1 - r2).powi(2) + z * z);
    MU_0 * z / ((r1 + r2).powi(2) + z * z).sqrt() * (e_factor * e - k)
}

#[test]
fn two_coaxial_loops_attract_with_the_derivative_of_their_mutual_inductance() {
    // Rings of round wire, a = 1 mm, on R = 20 mm and 30 mm, 10 mm apart, 100 A each in the
    // same sense: each pulls the other along the axis with I² ∂M/∂z, equal and opposite.
    let (a, r1, r2, gap, current) = (0.001, 0.02, 0.03, 0.01, 100.0);
    let domain = Rect::new(0.0, 0.08, -0.05, 0.06).unwrap();
    let rings = [(r1, 0.0), (r2, gap)].map(|(r, z)| (disc(r, z, a, 48, domain), 1.0));
    let run = adapt(
        &round_in_open_space(in_air(domain, "pair", current, rings)),
        None,
        &Settings::new(20_000),
        &mut (),
    )
    .unwrap();
    let exact = current * current * loop_attraction(r1, r2, gap);
    // Per radian: the whole turn is 2π times.
    let [lower, upper] = [0, 1].map(|i| 2.0 * PI * run.stats.regions[i].force[1]);
    assert!((lower - exact).abs() < 5e-3 * exact, "the lower ring is pulled up by {lower} N, not {exact} N");
    assert!(
        (upper + exact).abs() < 5e-3 * exact,
        "the upper ring is pulled down by {upper} N, not {exact} N"
    );
}
