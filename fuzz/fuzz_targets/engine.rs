//! The refinement on small inputs, with the mesh checked after every insertion.
//!
//! F is a grid of 2..=17 × 2..=17 finite values from the input (small integers, or any
//! finite f64), or an expression from a fixed list with constants from the input. The
//! rectangle is the unit square, the grid's index range, or four finite numbers from the
//! input when they make a valid `Rect`. Each input runs with both methods or both criteria
//! (as it says), a budget of 4..=300 vertices and, sometimes, a tolerance.
//!
//! Checks, through `Observer::inserted` (called once the mesh is consistent again, after
//! the flips): `check_invariants()` after every insertion, the new vertex's id, and for the
//! semi-recursive method `is_delaunay()` after every insertion. At the end: the stats agree
//! with the mesh, the budget holds, and the trace replays (`refine::trace::replay`) to the
//! same result, bit for bit, as fresh runs with budgets 4, about a third and about two thirds
//! of the vertex count, the full budget, and the tolerance of a step the run checked.
#![no_main]

use arbitrary::Arbitrary;
use libfuzzer_sys::fuzz_target;
use meshfit::geom::{Mesh, Rect};
use meshfit::refine::trace::{Recorder, replay};
use meshfit::refine::{Criterion, Method, Observer, Params, StopReason, refine};
use meshfit::result::RunResult;
use meshfit::source::{Expression, Grid, Source};

#[derive(Debug, Arbitrary)]
enum Values {
    /// Small integers: smooth and flat shapes, ties between values.
    Small(Vec<i8>),
    /// Any f64; an input with a non-finite one is skipped.
    Any(Vec<f64>),
}

#[derive(Debug, Arbitrary)]
enum SourceInput {
    Grid { nx: u8, ny: u8, values: Values },
    Expression { which: u8, a: f64, b: f64, c: f64 },
}

#[derive(Debug, Arbitrary)]
struct Input {
    source: SourceInput,
    /// `Some` to mesh this rectangle (if it is one) instead of the default.
    domain: Option<[f64; 4]>,
    /// 4..=300 vertices.
    budget: u16,
    tolerance: Option<f64>,
    /// Which runs: both methods with `criterion`, or both criteria with `method`.
    vary_criterion: bool,
    method: bool,
    criterion: bool,
}

/// Expressions with three constants `{a}`, `{b}`, `{c}`: kinks, cones, steps, peaks, ties.
const TEMPLATES: &[&str] = &[
    "sin({a}*x)*cos({b}*y) + {c}",
    "exp(-{a}*((x-{b})^2+(y-{c})^2))",
    "abs(x-{a}) + abs(y-{b})*{c}",
    "sqrt((x-{a})^2+(y-{b})^2)",
    "max(x*{a}, y*{b}, {c})",
    "floor({a}*x) + floor({b}*y)",
    "atan2(y-{b}, x-{a})",
    "tanh({a}*(x+y-{b}))*{c}",
    "{a}",
    "(x-{a})^2 - (y-{b})^2",
    "round({a}*x*y)*{c}",
    "x*{a} + y*{b} + {c}",
    "{a}*x^3 - {b}*y^2 + {c}*x*y",
    "signum(x-{a})*signum(y-{b})",
    "1/(1+{a}*(x^2+y^2))",
    "x % {a} + y % {b}",
];

/// `v` as expression text: `(1.5e-3)`, `(-2e300)`.
fn number(v: f64) -> String {
    format!("({v:e})")
}

/// Checks the mesh after every insertion.
struct Checker {
    delaunay: bool,
    insertions: usize,
}

impl Observer for Checker {
    fn inserted(&mut self, mesh: &Mesh, vertex: u32) {
        self.insertions += 1;
        if let Err(e) = mesh.check_invariants() {
            panic!("after inserting vertex {vertex}: {e}");
        }
        assert_eq!(vertex as usize + 1, mesh.num_vertices(), "vertex ids are not in insertion order");
        if self.delaunay {
            if let Some(e) = mesh.find_non_delaunay_edge() {
                panic!("semi-recursive mesh not Delaunay after inserting vertex {vertex}: half-edge {e}");
            }
        }
    }
}

/// Everything a client sees of a run, with exact bits (NaN included) for comparison.
fn seen(run: meshfit::refine::Refinement) -> String {
    format!("{:?}", RunResult::from(run))
}

fn source_of(input: &SourceInput) -> Option<Source> {
    match input {
        SourceInput::Grid { nx, ny, values } => {
            let (nx, ny) = (2 + usize::from(nx % 16), 2 + usize::from(ny % 16));
            let n = nx * ny;
            let values: Vec<f64> = match values {
                Values::Small(v) if !v.is_empty() => (0..n).map(|k| f64::from(v[k % v.len()])).collect(),
                Values::Any(v) if !v.is_empty() => (0..n).map(|k| v[k % v.len()]).collect(),
                _ => return None,
            };
            if values.iter().any(|v| !v.is_finite()) {
                return None;
            }
            Some(Source::Grid(Grid::new(nx, ny, values).expect("a valid grid")))
        }
        &SourceInput::Expression { which, a, b, c } => {
            if ![a, b, c].iter().all(|v| v.is_finite()) {
                return None;
            }
            let template = TEMPLATES[usize::from(which) % TEMPLATES.len()];
            let text =
                template.replace("{a}", &number(a)).replace("{b}", &number(b)).replace("{c}", &number(c));
            let e = Expression::parse(&text).unwrap_or_else(|e| panic!("template {text:?}: {e}"));
            Some(Source::Expression(e))
        }
    }
}

fn run(source: &Source, rect: Rect, params: &Params) {
    let semi = params.method() == Method::SemiRecursive;
    let mut checker = Checker { delaunay: semi, insertions: 0 };
    let mut recorder = Recorder::new(&mut checker, params);
    let Ok(full) = refine(source, rect, params, &mut recorder) else {
        return; // F not finite somewhere it was needed: the service reports that.
    };
    let trace = recorder.finish(full.stats.stop);
    let mesh = &full.mesh;
    let n = mesh.num_vertices();
    assert_eq!(checker.insertions + 4, n, "an insertion was not observed");
    assert!(n <= params.max_vertices(), "{n} vertices above the budget {}", params.max_vertices());
    assert_eq!(full.stats.vertices, n);
    assert_eq!(full.stats.triangles, mesh.num_triangles());
    assert_eq!(full.stats.delaunay, mesh.is_delaunay());
    if semi {
        assert!(full.stats.delaunay, "semi-recursive mesh is not Delaunay");
    }
    if full.stats.stop == StopReason::MaxVertices {
        assert_eq!(n, params.max_vertices());
    }
    if let Some(errors) = &full.triangle_errors {
        assert_eq!(errors.len(), mesh.num_triangles());
    }
    mesh.check_invariants().unwrap_or_else(|e| panic!("final mesh: {e}"));

    // Replays of prefixes against fresh runs of the smaller requests.
    let vertices = mesh.vertices().to_vec();
    let mut cases: Vec<(usize, Option<f64>)> =
        vec![(4, None), ((n / 3).max(4), None), ((2 * n / 3).max(4), None), (params.max_vertices(), None)];
    if let Some(&w) = trace.worst.get(trace.worst.len() / 2) {
        if w.is_finite() && w >= 0.0 {
            cases.push((params.max_vertices(), Some(w)));
        }
    }
    for (budget, tolerance) in cases {
        // The run's own tolerance still stops a smaller request where it stopped the run.
        let tolerance = tolerance.or(params.tolerance());
        let mut p = Params::builder(budget).method(params.method()).criterion(params.criterion());
        if let Some(t) = tolerance {
            p = p.tolerance(t);
        }
        let p = p.build().expect("a budget >= 4 and a finite tolerance");
        let replayed = replay(&trace, &vertices, budget, tolerance)
            .unwrap_or_else(|| panic!("({budget}, {tolerance:?}) of a run of {n} vertices is not replayed"));
        let fresh = refine(source, rect, &p, &mut ()).expect("a prefix of a run that succeeded");
        assert_eq!(
            seen(replayed),
            seen(fresh),
            "replay of ({budget}, {tolerance:?}) differs from a fresh run"
        );
    }
}

fuzz_target!(|input: Input| {
    let Some(source) = source_of(&input.source) else { return };
    let rect = input
        .domain
        .and_then(|[a, b, c, d]| Rect::new(a, b, c, d).ok())
        .unwrap_or_else(|| source.default_domain());
    let source = source.with_domain(rect);
    let budget = 4 + usize::from(input.budget % 297);
    let mut base = Params::builder(budget);
    if let Some(t) = input.tolerance.filter(|t| t.is_finite() && *t >= 0.0) {
        base = base.tolerance(t);
    }
    let method = if input.method { Method::Recursive } else { Method::SemiRecursive };
    let criterion = if input.criterion { Criterion::Variation } else { Criterion::Error };
    let runs: [(Method, Criterion); 2] = if input.vary_criterion {
        [(method, Criterion::Error), (method, Criterion::Variation)]
    } else {
        [(Method::SemiRecursive, criterion), (Method::Recursive, criterion)]
    };
    for (method, criterion) in runs {
        let params = base.clone().method(method).criterion(criterion).build().expect("budget in 4..=300");
        run(&source, rect, &params);
    }
});
