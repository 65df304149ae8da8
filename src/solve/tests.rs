//! Tests of the P1 solver: the patch test, convergence rates on uniform meshes, a symmetric
//! inclusion, determinism and the errors that name a point.

use super::coefficients::TriangleCoefficients;
use super::*;
use crate::geom::{Point, Rect, Vertex};
use crate::refine::{Criterion, Method, Params, refine};
use std::f64::consts::PI;

/// The rectangle cut into n × n cells, each split by its rising diagonal:
///
/// ```text
///  v01 ── v11
///   │   ╱  │
///   │  ╱   │
///  v00 ── v10     triangles [v00, v10, v11] and [v00, v11, v01], both CCW
/// ```
///
/// Vertex (i, j) is at index j (n + 1) + i, at (x0 + i w / n, y0 + j h / n) with the last row
/// and column set to x1 and y1 exactly, so the boundary test sees them.
pub(super) fn uniform(rect: Rect, n: u32) -> (Vec<Point>, Vec<[u32; 3]>) {
    let coord =
        |lo: f64, hi: f64, i: u32| if i == n { hi } else { lo + (hi - lo) * f64::from(i) / f64::from(n) };
    let mut points = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            points.push(Point::new(coord(rect.x0(), rect.x1(), i), coord(rect.y0(), rect.y1(), j)));
        }
    }
    let id = |i: u32, j: u32| j * (n + 1) + i;
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (points, triangles)
}

/// A mesh from the crate's own refinement of `f` on `rect`.
fn refined(rect: Rect, n: usize, method: Method, f: fn(f64, f64) -> f64) -> (Vec<Vertex>, Vec<[u32; 3]>) {
    let params = Params::builder(n).method(method).criterion(Criterion::Variation).build().unwrap();
    let r = refine(&f, rect, &params, &mut ()).unwrap();
    (r.mesh.vertices().to_vec(), r.mesh.triangles().collect())
}

/// Least-squares slope of log(err) against log(n).
pub(super) fn slope(samples: &[(f64, f64)]) -> f64 {
    let pts: Vec<(f64, f64)> = samples.iter().map(|&(n, e)| (n.ln(), e.ln())).collect();
    let m = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / m, pts.iter().map(|p| p.1).sum::<f64>() / m);
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    sxy / sxx
}

// ---- Patch test ------------------------------------------------------------------------------

fn linear(x: f64, y: f64) -> f64 {
    1.0 + 2.0 * x - 3.0 * y
}

/// The largest |u_h − (1 + 2x − 3y)| over the vertices, solving with g = 1 + 2x − 3y, f = 0.
fn patch_error<P: Position>(vertices: &[P], triangles: &[[u32; 3]], rect: Rect) -> (f64, Solution) {
    let s = solve(&Problem::new(rect).with_g(linear), vertices, triangles).unwrap();
    assert!(s.num_unknowns > 0, "the mesh has interior vertices");
    let worst = vertices.iter().zip(&s.u).map(|(v, u)| (u - linear(v.position().x, v.position().y)).abs());
    (worst.fold(0.0, f64::max), s)
}

/// The smallest 2 area / (longest side)² of the mesh's triangles: height over length, ≤ √3/2.
fn min_aspect<P: Position>(vertices: &[P], triangles: &[[u32; 3]]) -> f64 {
    let aspect = |t: &[u32; 3]| {
        let p = t.map(|v| vertices[v as usize].position());
        let det = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
        det / (0..3).map(|i| p[i].distance_sq(p[(i + 1) % 3])).fold(0.0, f64::max)
    };
    triangles.iter().map(aspect).fold(f64::INFINITY, f64::min)
}

fn patch_rect() -> Rect {
    Rect::new(-1.0, 2.0, 0.5, 1.5).unwrap()
}

fn bump(x: f64, y: f64) -> f64 {
    (-4.0 * (x * x + (y - 1.0) * (y - 1.0))).exp()
}

#[test]
fn linear_boundary_data_is_reproduced_to_1e_12_on_refined_meshes_of_both_methods() {
    let cases = [(Method::SemiRecursive, [50, 400, 3000].as_slice()), (Method::Recursive, &[50, 100])];
    for (method, sizes) in cases {
        for &n in sizes {
            let (vertices, triangles) = refined(patch_rect(), n, method, bump);
            let (error, s) = patch_error(&vertices, &triangles, patch_rect());
            assert!(error <= 1e-12, "{method} n = {n}: max nodal error {error:e}");
            for (t, g) in s.gradients.iter().enumerate() {
                let ok = (g[0] - 2.0).abs() <= 1e-8 && (g[1] + 3.0).abs() <= 1e-8;
                assert!(ok, "{method} n = {n}: ∇u_h = {g:?} on triangle {t}");
            }
        }
    }
}

#[test]
fn on_needle_meshes_the_patch_test_error_stays_within_rounding_over_the_worst_aspect() {
    // The Recursive method never flips, so its triangles thin out to height/length ≈ 4e-9 by
    // n = 1000, and the stiffness matrix's conditioning grows like the inverse. Measured:
    // n = 200: 3.3e-12 (aspect 1.3e-5), n = 400: 4.0e-11 (4.3e-7), n = 1000: 1.6e-8 (4.5e-9).
    for n in [200, 400, 1000] {
        let (vertices, triangles) = refined(patch_rect(), n, Method::Recursive, bump);
        let aspect = min_aspect(&vertices, &triangles);
        let (error, _) = patch_error(&vertices, &triangles, patch_rect());
        let bound = 8.0 * f64::EPSILON / aspect;
        assert!(error <= bound, "n = {n}: error {error:e} > {bound:e} (worst aspect {aspect:e})");
    }
}

#[test]
fn linear_boundary_data_is_reproduced_to_1e_12_on_a_uniform_mesh() {
    let rect = Rect::new(0.0, 3.0, -1.0, 1.0).unwrap();
    let (points, triangles) = uniform(rect, 12);
    let (error, s) = patch_error(&points, &triangles, rect);
    assert!(error <= 1e-12, "max nodal error {error:e}");
    for (t, g) in s.gradients.iter().enumerate() {
        assert!((g[0] - 2.0).abs() <= 1e-12 && (g[1] + 3.0).abs() <= 1e-12, "∇u_h = {g:?} on triangle {t}");
    }
}

// ---- Convergence -----------------------------------------------------------------------------

#[test]
fn smooth_solution_converges_at_rate_one_half_in_energy_and_one_in_l2_per_vertex() {
    let exact = |x: f64, y: f64| (PI * x).sin() * (PI * y).sin();
    let gradient =
        |x: f64, y: f64| [PI * (PI * x).cos() * (PI * y).sin(), PI * (PI * x).sin() * (PI * y).cos()];
    let problem = Problem::new(Rect::unit()).with_f(|x, y| 2.0 * PI * PI * exact(x, y));
    let (mut energy, mut l2) = (Vec::new(), Vec::new());
    for n in [8, 16, 32, 64] {
        let (points, triangles) = uniform(Rect::unit(), n);
        let s = solve(&problem, &points, &triangles).unwrap();
        let e = s.errors(&problem, &points, &triangles, exact, gradient).unwrap();
        let vertices = points.len() as f64;
        energy.push((vertices, e.energy));
        l2.push((vertices, e.l2));
        assert!(e.max_nodal < 0.05, "n = {n}: max nodal error {}", e.max_nodal);
    }
    // Measured: −0.523 and −1.045 over N = 81, 289, 1089, 4225.
    let (se, sl) = (slope(&energy), slope(&l2));
    assert!((se + 0.5).abs() < 0.1, "energy-norm slope {se}, samples {energy:?}");
    assert!((sl + 1.0).abs() < 0.1, "L2 slope {sl}, samples {l2:?}");
}

// ---- Variable k ------------------------------------------------------------------------------

/// f = 1, g = 0, k = 10 in [0.25, 0.5]², a square on the line y = x and on mesh lines.
fn inclusion() -> Problem<'static> {
    let rect = Rect::new(0.25, 0.5, 0.25, 0.5).unwrap();
    Problem::new(Rect::unit()).with_f(|_, _| 1.0).with_region(Region::rect(rect, Some(10.0), None))
}

#[test]
fn an_inclusion_symmetric_about_the_diagonal_gives_a_symmetric_solution() {
    // The uniform mesh maps to itself under (x, y) → (y, x): its diagonals lie along y = x.
    let n = 16;
    let (points, triangles) = uniform(Rect::unit(), n);
    let s = solve(&inclusion(), &points, &triangles).unwrap();
    let id = |i: u32, j: u32| (j * (n + 1) + i) as usize;
    for j in 0..=n {
        for i in 0..j {
            let (a, b) = (s.u[id(i, j)], s.u[id(j, i)]);
            assert!((a - b).abs() <= 1e-14 * a.abs().max(1e-3), "u({i}, {j}) = {a} but u({j}, {i}) = {b}");
        }
    }
}

#[test]
fn the_inclusion_energy_is_positive_and_within_one_percent_of_a_finer_mesh() {
    let energy = |n| {
        let (points, triangles) = uniform(Rect::unit(), n);
        solve(&inclusion(), &points, &triangles).unwrap().energy
    };
    let (coarse, fine) = (energy(32), energy(64));
    assert!(coarse > 0.0 && fine > 0.0);
    // With g = 0 the discrete energy is ½ (f, u_h), and on nested meshes it grows towards the
    // exact value. Measured: 0.016838 (n = 16), 0.017015 (32), 0.017063 (64), 0.017076 (128).
    assert!(fine >= coarse, "coarse {coarse}, fine {fine}");
    assert!((fine - coarse) / fine < 0.01, "coarse {coarse}, fine {fine}");
}

#[test]
fn a_region_side_that_cuts_a_triangle_counts_with_its_exact_share_of_the_area() {
    // The triangle (0,0), (1,0), (0,1) has 0.28125 of its 0.5 on the side x ≥ 0.25.
    let points = [Point::new(0.0, 0.0), Point::new(1.0, 0.0), Point::new(0.0, 1.0)];
    let e = Element::new(&points, [0, 1, 2], 0).unwrap();
    let region = Region::rect(Rect::new(0.25, 2.0, -1.0, 2.0).unwrap(), Some(3.0), Some(2.0));
    let problem = Problem::new(Rect::new(-1.0, 2.0, -1.0, 2.0).unwrap()).with_region(region);
    let c = TriangleCoefficients::of(&problem, &e, 0).unwrap();
    let share = 0.28125 / 0.5;
    assert!((c.k - (3.0 * share + (1.0 - share))).abs() < 1e-14, "mean k {}", c.k);
    assert!((c.f_sq - 4.0 * share).abs() < 1e-14, "mean f² {}", c.f_sq);
    // ∫ f φᵢ sums to ∫ f = 2 · 0.28125 (the hat functions sum to 1); φ₁ = x, and the part's
    // centroid is at x = 0.5, so ∫ f φ₁ = 2 · 0.28125 · 0.5.
    let total: f64 = c.load.iter().sum::<f64>() * e.area();
    assert!((total - 2.0 * 0.28125).abs() < 1e-14, "∫ f = {total}");
    assert!((c.load[1] * e.area() - 2.0 * 0.28125 * 0.5).abs() < 1e-14, "∫ f φ₁ = {}", c.load[1] * e.area());
}

#[test]
fn a_later_region_overrides_only_the_fields_it_sets() {
    let big = Region::rect(Rect::unit(), Some(2.0), Some(3.0));
    let small = Region::rect(Rect::new(0.0, 0.5, 0.0, 0.5).unwrap(), None, Some(5.0));
    let problem = Problem::new(Rect::unit()).with_k(|_, _| 7.0).with_region(big).with_region(small);
    assert_eq!(problem.k_and_f(Point::new(0.25, 0.25)), (2.0, 5.0));
    assert_eq!(problem.k_and_f(Point::new(0.75, 0.75)), (2.0, 3.0));
    assert_eq!(problem.k_at(Point::new(0.25, 0.25)), 2.0);
}

// ---- Determinism -----------------------------------------------------------------------------

#[test]
fn solving_the_same_problem_twice_gives_the_same_bits() {
    let rect = Rect::unit();
    let (vertices, triangles) = refined(rect, 800, Method::SemiRecursive, |x, y| (5.0 * x * y).sin());
    let problem = inclusion().with_k(|x, y| 1.0 + x * y).with_g(|x, y| x - y * y);
    let (a, b) =
        (solve(&problem, &vertices, &triangles).unwrap(), solve(&problem, &vertices, &triangles).unwrap());
    let bits = |s: &Solution| {
        let mut v: Vec<u64> = s.u.iter().map(|u| u.to_bits()).collect();
        v.extend(s.gradients.iter().flat_map(|g| g.map(f64::to_bits)));
        v.push(s.energy.to_bits());
        v
    };
    assert_eq!(bits(&a), bits(&b));
}

// ---- Bad input -------------------------------------------------------------------------------

#[test]
fn zero_k_in_a_region_names_the_quadrature_point() {
    let (points, triangles) = uniform(Rect::unit(), 4);
    let rect = Rect::new(0.5, 0.75, 0.5, 0.75).unwrap();
    let problem = Problem::new(Rect::unit()).with_region(Region::rect(rect, Some(0.0), None));
    let err = solve(&problem, &points, &triangles).unwrap_err();
    let SolveError::InvalidK { x, y, value, triangle } = err else { panic!("{err:?}") };
    assert_eq!(value, 0.0);
    assert!(problem.regions()[0].contains(Point::new(x, y)), "({x}, {y}) is in the region");
    // The first triangle in order with a quadrature point in the region: cell (2, 2), lower half.
    assert_eq!(triangle, 2 * (2 * 4 + 2));
    // The message names the point, not the internal index.
    assert_eq!(err.to_string(), format!("k = 0 at ({x}, {y}); k must be finite and positive"));
}

#[test]
fn negative_or_nan_k_from_the_closure_is_rejected() {
    let (points, triangles) = uniform(Rect::unit(), 2);
    for k in [-1.0, f64::NAN, f64::INFINITY] {
        let problem = Problem::new(Rect::unit()).with_k(move |_, _| k);
        assert!(matches!(
            solve(&problem, &points, &triangles),
            Err(SolveError::InvalidK { triangle: 0, .. })
        ));
    }
}

#[test]
fn non_finite_f_and_g_name_the_point() {
    let (points, triangles) = uniform(Rect::unit(), 2);
    let problem = Problem::new(Rect::unit()).with_f(|x, _| if x > 0.5 { f64::NAN } else { 0.0 });
    let err = solve(&problem, &points, &triangles).unwrap_err();
    assert!(matches!(err, SolveError::NonFiniteF { x, .. } if x > 0.5), "{err:?}");

    let problem =
        Problem::new(Rect::unit()).with_g(|x, y| if (x, y) == (1.0, 0.5) { f64::INFINITY } else { 0.0 });
    let err = solve(&problem, &points, &triangles).unwrap_err();
    assert_eq!(err, SolveError::NonFiniteG { x: 1.0, y: 0.5, value: f64::INFINITY, vertex: 5 });
}

#[test]
fn a_clockwise_triangle_is_rejected() {
    let (points, mut triangles) = uniform(Rect::unit(), 2);
    triangles[3].swap(1, 2);
    let err = solve(&Problem::new(Rect::unit()), &points, &triangles).unwrap_err();
    assert!(matches!(err, SolveError::DegenerateTriangle { triangle: 3, area } if area < 0.0), "{err:?}");
}

#[test]
fn an_interior_vertex_in_no_triangle_makes_the_matrix_singular() {
    let (mut points, triangles) = uniform(Rect::unit(), 2);
    points.push(Point::new(0.3, 0.3));
    let err = solve(&Problem::new(Rect::unit()), &points, &triangles).unwrap_err();
    assert!(matches!(err, SolveError::NotPositiveDefinite { unknowns: 2, .. }), "{err:?}");
}
