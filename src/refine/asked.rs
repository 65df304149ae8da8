//! A refinement of an F that the caller evaluates, a batch of points at a time (ask/tell).
//!
//! The engine is not paused between batches: nothing is held while the caller evaluates.
//! Each [`next`] replays the whole refinement from the corners over the values told so far,
//! every midpoint not yet told standing in with the mean of its edge's ends (the linear
//! interpolant, as if F were flat there), until `batch` untold midpoints are met: those are
//! the next points to ask, in the order the engine met them. Once a replay needs no untold
//! point it is the engine's own run over the told values, so the mesh depends on those values
//! only: the same values give the same bytes, whoever told them and whenever.
//!
//! A replay costs what a refinement of its size costs, once a batch: a job of n vertices in
//! batches of k replays about n²/(2k) insertions, for an F whose evaluations take seconds. A
//! batch of 1 asks exactly the points the sequential algorithm would. A larger batch guesses
//! ahead: when a told value differs from its stand-in, the replay may turn elsewhere, and a
//! point asked on the guess goes unused (`Next::Done` counts them; `examples/asked_batches.rs`
//! measures how many).

use super::driver::{finished, resume};
use super::estimator::{Estimator, Field};
use super::floors::Floors;
use super::outcome::Refinement;
use super::params::{Criterion, Params};
use crate::geom::{Mesh, Point, Rect, Vertex};
use std::collections::{HashMap, HashSet};
use std::time::{Duration, Instant};

/// What the caller said of a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Told {
    /// F there.
    Value(f64),
    /// F could not be had there: the point takes the mean of its edge's ends, as an untold
    /// one stands in, and keeps it (its triangles are refined as the interpolant says).
    Failed,
}

/// The values told so far, by point (bit for bit as the engine asked it).
#[derive(Debug, Clone, Default)]
pub struct Values {
    told: HashMap<[u64; 2], Told>,
}

impl Values {
    /// No values.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records what was told of `p`; the first word stands (the caller checks repeats). A
    /// value that is not finite is a failure: a mesh never holds NaN or infinity.
    pub fn tell(&mut self, p: Point, told: Told) {
        let told = match told {
            Told::Value(v) if !v.is_finite() => Told::Failed,
            told => told,
        };
        self.told.entry(key(p)).or_insert(told);
    }

    /// What was told of `p`, if anything.
    pub fn get(&self, p: Point) -> Option<Told> {
        self.told.get(&key(p)).copied()
    }

    /// How many points were told.
    pub fn len(&self) -> usize {
        self.told.len()
    }

    /// Whether nothing was told.
    pub fn is_empty(&self) -> bool {
        self.told.is_empty()
    }
}

/// A point's bits: points are the engine's own, compared exactly.
fn key(p: Point) -> [u64; 2] {
    [(p.x + 0.0).to_bits(), (p.y + 0.0).to_bits()]
}

/// What the refinement needs next.
#[derive(Debug)]
pub enum Next {
    /// F at these points, none told yet, in the order the engine met them.
    Ask(Vec<Point>),
    /// Every vertex is told: the refinement, and how many told points it left unused.
    Done(Box<Refinement>, usize),
}

/// Why a client refinement cannot go on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AskError {
    /// Only criterion `variation` needs F at the vertices alone.
    #[error("a refinement the client evaluates ranks edges by variation, not {0:?}")]
    Criterion(Criterion),
    /// A time limit would make the mesh depend on the machine's speed.
    #[error("a refinement the client evaluates has no time limit")]
    TimeLimit,
    /// A corner failed: the mesh has no values to start from.
    #[error("F failed at the corner ({x}, {y}): a refinement starts from the four corners", x = .0.x, y = .0.y)]
    Corner(Point),
}

/// The next step of refining `rect` by `params` over `values`: the next at most `batch`
/// points to ask (at least 1; the four corners come first, together), or the finished
/// refinement.
///
/// # Errors
/// A criterion other than `variation`, a time limit, or a corner the caller could not
/// evaluate.
pub fn next(rect: Rect, params: &Params, values: &Values, batch: usize) -> Result<Next, AskError> {
    if params.criterion() != Criterion::Variation {
        return Err(AskError::Criterion(params.criterion()));
    }
    if params.time_limit().is_some() {
        return Err(AskError::TimeLimit);
    }
    let start = Instant::now();
    let corners = rect.corners();
    let untold: Vec<Point> = corners.iter().copied().filter(|&p| values.get(p).is_none()).collect();
    if !untold.is_empty() {
        return Ok(Next::Ask(untold));
    }
    let z = corners.map(|p| values.get(p));
    let mut z4 = [0.0; 4];
    for (k, told) in z.iter().enumerate() {
        match told {
            Some(Told::Value(v)) => z4[k] = *v,
            _ => return Err(AskError::Corner(corners[k])),
        }
    }
    let mut mesh = Mesh::with_capacity(rect, z4, params.max_vertices());
    let mut replay = Replay { values, asked: Vec::new(), seen: HashSet::new(), batch: batch.max(1), used: 4 };
    match resume(&mut mesh, &mut replay, params, Floors::of_rect(rect), &mut ()) {
        Err(Full) => Ok(Next::Ask(replay.asked)),
        Ok(_) if !replay.asked.is_empty() => Ok(Next::Ask(replay.asked)),
        Ok(round) => {
            let unused = values.len().saturating_sub(replay.used as usize);
            let refinement = finished(mesh, round, params, replay.used, start, Duration::ZERO);
            Ok(Next::Done(Box::new(refinement), unused))
        }
    }
}

/// A full batch: the replay stops there.
struct Full;

/// The engine's values during a replay: told ones, and stand-ins for the rest.
struct Replay<'v> {
    values: &'v Values,
    /// Untold points met, in order, and which were met.
    asked: Vec<Point>,
    seen: HashSet<[u64; 2]>,
    batch: usize,
    /// Told points the replay used.
    used: u64,
}

impl Field for Replay<'_> {
    type Error = Full;

    fn midpoint(&mut self, a: Vertex, b: Vertex, m: Point) -> Result<f64, Full> {
        let stand_in = 0.5 * (a.z + b.z);
        match self.values.get(m) {
            Some(Told::Value(v)) => {
                self.used += 1;
                Ok(v)
            }
            Some(Told::Failed) => {
                self.used += 1;
                Ok(stand_in)
            }
            None => {
                if self.seen.insert(key(m)) {
                    self.asked.push(m);
                }
                if self.asked.len() >= self.batch { Err(Full) } else { Ok(stand_in) }
            }
        }
    }

    fn evaluations(&self) -> u64 {
        self.used
    }
}

impl Estimator for Replay<'_> {
    /// Never called: [`next`] runs criterion `variation` only, which ranks edges by the
    /// vertices' values.
    fn estimate(&mut self, _mesh: &Mesh, _t: u32, _known: [Option<f64>; 3]) -> Result<(f64, [f64; 3]), Full> {
        unreachable!("criterion variation estimates no triangle")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::{Method, refine};
    use proptest::prelude::*;

    /// Plays the caller: asks until done, telling F at every point asked.
    fn played(
        f: impl Fn(f64, f64) -> f64,
        rect: Rect,
        params: &Params,
        batch: usize,
    ) -> (Refinement, usize, usize) {
        let (mut values, mut asked) = (Values::new(), 0);
        loop {
            match next(rect, params, &values, batch).unwrap() {
                Next::Ask(points) => {
                    assert!(!points.is_empty() && points.len() <= batch.max(4), "{} points", points.len());
                    for p in points {
                        assert!(values.get(p).is_none(), "{p:?} asked again");
                        values.tell(p, Told::Value(f(p.x, p.y)));
                        asked += 1;
                    }
                }
                Next::Done(refinement, unused) => return (*refinement, asked, unused),
            }
        }
    }

    fn params(max_vertices: usize, method: Method) -> Params {
        Params::builder(max_vertices).criterion(Criterion::Variation).method(method).build().unwrap()
    }

    fn same_mesh(a: &Refinement, b: &Refinement) {
        assert_eq!(a.mesh.vertices(), b.mesh.vertices());
        assert_eq!(a.mesh.triangles().collect::<Vec<_>>(), b.mesh.triangles().collect::<Vec<_>>());
    }

    #[test]
    fn one_point_a_batch_asks_exactly_the_points_of_the_sequential_run() {
        let f = |x: f64, y: f64| (3.0 * x).sin() * (2.0 * y).cos() + x * y;
        let rect = Rect::new(-1.0, 2.0, 0.0, 1.5).unwrap();
        let params = params(300, Method::SemiRecursive);
        let (asked, points, unused) = played(f, rect, &params, 1);
        let direct = refine(&f, rect, &params, &mut ()).unwrap();
        same_mesh(&asked, &direct);
        assert_eq!((points, unused), (300, 0), "one evaluation a vertex, none wasted");
        assert_eq!(asked.stats.evaluations, direct.stats.evaluations);
        // Fifty at a time guesses ahead, and some guesses miss: the same mesh, points unused.
        let (ahead, points, unused) = played(f, rect, &params, 50);
        same_mesh(&ahead, &direct);
        assert!(unused > 0 && points == 300 + unused, "{points} asked, {unused} unused");
    }

    #[test]
    fn a_failed_point_stands_in_with_its_edges_mean_and_a_failed_corner_is_an_error() {
        let rect = Rect::unit();
        let params = params(60, Method::Recursive);
        let mut values = Values::new();
        for (k, p) in rect.corners().into_iter().enumerate() {
            values.tell(p, Told::Value(k as f64));
        }
        let Next::Ask(first) = next(rect, &params, &values, 1).unwrap() else { panic!("a first midpoint") };
        values.tell(first[0], Told::Failed);
        // Told anything but the failed point: the mesh keeps the stand-in there.
        loop {
            match next(rect, &params, &values, 8).unwrap() {
                Next::Ask(points) => points.into_iter().for_each(|p| values.tell(p, Told::Value(p.x * p.x))),
                Next::Done(r, _) => {
                    let v = r.mesh.vertices()[4];
                    assert_eq!((v.x, v.y), (first[0].x, first[0].y));
                    // The worst edge of S₄ is P4P1, |3 − 0|: its midpoint stands in with 1.5.
                    assert_eq!(v.z, 1.5);
                    break;
                }
            }
        }
        // A corner told NaN failed, and the mesh cannot start.
        let mut failed = Values::new();
        for p in rect.corners() {
            failed.tell(p, Told::Value(if p == Point::new(0.0, 0.0) { f64::NAN } else { 1.0 }));
        }
        assert_eq!(next(rect, &params, &failed, 4).unwrap_err(), AskError::Corner(Point::new(0.0, 0.0)));
        let error = Params::builder(60).build().unwrap();
        assert!(matches!(next(rect, &error, &values, 4), Err(AskError::Criterion(_))));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Whatever the batch, the finished mesh is the engine's run over F: a guess ahead
        /// only costs points left unused.
        #[test]
        fn every_batch_size_finishes_with_the_engines_own_mesh(
            batch in 1usize..80,
            a in 0.5f64..6.0,
            b in -3.0f64..3.0,
            recursive in any::<bool>(),
        ) {
            let f = move |x: f64, y: f64| (a * x).sin() + b * x * y * y;
            let rect = Rect::new(0.0, 1.0, -1.0, 1.0).unwrap();
            let method = if recursive { Method::Recursive } else { Method::SemiRecursive };
            let params = params(200, method);
            let (asked, points, unused) = played(f, rect, &params, batch);
            same_mesh(&asked, &refine(&f, rect, &params, &mut ()).unwrap());
            prop_assert_eq!(points as u64, asked.stats.evaluations + unused as u64);
        }
    }
}
