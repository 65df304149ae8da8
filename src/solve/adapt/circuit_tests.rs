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

#[test]
fn a_two_wire_line_has_the_inductance_of_its_formula_and_both_agree_with_the_energy() {
    // Round wires of radius a, centres d apart, carrying ±I spread evenly (direct current):
    // outside, each acts as a line current at its centre, so per metre L = μ0/π · ln(d / a)
    // plus μ0/8π inside each. (acosh(d / 2a) is for currents pushed to the surfaces.)
    let (a, d, current) = (0.002, 0.02, 10.0);
    let domain = Rect::new(-0.4, 0.4, -0.4, 0.4).unwrap();
    let problem = Problem::new(domain)
        .with_k(|_, _| 1.0 / MU_0)
        .with_circuit(Circuit { name: "line".into(), current })
        .with_region(coil(disc(-d / 2.0, 0.0, a, 64, domain), 1.0, current))
        .with_region(coil(disc(d / 2.0, 0.0, a, 64, domain), -1.0, current));
    let run = adapt(&problem, None, &Settings::new(20_000), &mut ()).unwrap();
    let line = run.stats.circuits["line"];
    let exact = MU_0 / PI * (d / a).ln() + 2.0 * MU_0 / (8.0 * PI);
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
        let coefficients: Vec<_> = (triangles.iter().enumerate())
            .map(|(t, &tri)| {
                TriangleCoefficients::of(&problem, &Element::new(&points, tri, t).unwrap(), t).unwrap()
            })
            .collect();
        super::circuits::measure(&problem, &points, &solution.u, &triangles, &coefficients).unwrap()["coil"]
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
