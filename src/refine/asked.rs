//! A refinement of an F that the caller evaluates, a batch of points at a time (ask/tell).
//!
//! The engine is not paused between batches: nothing is held while the caller evaluates.
//! Each [`next`] replays the whole refinement from the corners over the values told so far,
//! every midpoint not yet told standing in with the criterion's guess at F there (for
//! `curvature` the cubic its edge's ends' values and gradients define, for `variation` the
//! mean of its edge's ends), until `batch` untold midpoints are met: those are
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
use super::observer::Observer;
use super::outcome::Refinement;
use super::params::{Criterion, Params};
use super::run::Round;
use crate::geom::{Mesh, Point, Rect, Vertex};
use std::collections::{HashMap, HashSet};
use std::time::{Duration, Instant};

/// What the caller said of a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Told {
    /// F there.
    Value(f64),
    /// F could not be had there: the point keeps the stand-in an untold one has (the
    /// criterion's guess), and its triangles are refined as if F were that.
    Failed,
}

impl Told {
    /// What a value says: F, or a failure (none, or not finite).
    pub fn of(value: Option<f64>) -> Told {
        match value {
            Some(v) if v.is_finite() => Told::Value(v),
            _ => Told::Failed,
        }
    }

    /// F, or `None` for a failure.
    pub fn value(self) -> Option<f64> {
        match self {
            Told::Value(v) => Some(v),
            Told::Failed => None,
        }
    }
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

    /// Every point told and what was told of it, in no particular order.
    pub fn iter(&self) -> impl Iterator<Item = (Point, Told)> + '_ {
        let point = |k: &[u64; 2]| Point::new(f64::from_bits(k[0]), f64::from_bits(k[1]));
        self.told.iter().map(move |(k, &told)| (point(k), told))
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
    /// Only criteria `curvature` and `variation` need F at the vertices alone.
    #[error("a refinement the client evaluates ranks edges by curvature or variation, not {0}")]
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
/// refinement. A replay from the corners: [`Asker::next`] does the same from where the last
/// replay left off.
///
/// # Errors
/// Criterion `error`, a time limit, or a corner the caller could not evaluate.
pub fn next(rect: Rect, params: &Params, values: &Values, batch: usize) -> Result<Next, AskError> {
    Asker::default().next(rect, params, values, batch)
}

/// A client refinement's memory between batches: the mesh where the last replay first met a
/// point not told (its *frontier*). Everything before it was built from told values, and a
/// told value never changes, so the next replay starts there instead of at the corners: a
/// batch costs a rebuild of the queue (a pass over the vertices) and its own steps, not the
/// whole refinement again. The finished refinement is always replayed from the corners, so
/// its stats (flips, retired edges, history), like its mesh, depend on the values alone.
#[derive(Debug, Clone, Default)]
pub struct Asker {
    frontier: Option<Mesh>,
}

impl Asker {
    /// [`next`], from the last frontier, for the same `rect` and `params` and values that
    /// only grow.
    ///
    /// # Errors
    /// As [`next`].
    pub fn next(
        &mut self,
        rect: Rect,
        params: &Params,
        values: &Values,
        batch: usize,
    ) -> Result<Next, AskError> {
        if params.criterion() == Criterion::Error {
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
        let mut z4 = [0.0; 4];
        for (k, &p) in corners.iter().enumerate() {
            match values.get(p) {
                Some(Told::Value(v)) => z4[k] = v,
                _ => return Err(AskError::Corner(p)),
            }
        }
        if let Some(frontier) = self.frontier.take() {
            // A replay from the frontier that needs nothing more is not the finished
            // refinement: its stats count from the frontier, and its state was rebuilt there
            // (the queue from the mesh's edges), which can choose, rarely, otherwise than the
            // run from the corners. So only its asks are taken.
            if let Err(points) = self.replay(frontier, rect, params, values, batch) {
                return Ok(Next::Ask(points));
            }
        }
        let corners = Mesh::with_capacity(rect, z4, params.max_vertices());
        match self.replay(corners, rect, params, values, batch) {
            Ok((mesh, round, used)) => {
                let unused = values.len().saturating_sub(used as usize);
                let refinement = finished(mesh, round, params, used, start, Duration::ZERO);
                Ok(Next::Done(Box::new(refinement), unused))
            }
            Err(points) => Ok(Next::Ask(points)),
        }
    }

    /// A replay from `mesh`: the refinement and the told points it used when it met no untold
    /// point, else the points to ask, its frontier kept for the next replay.
    fn replay(
        &mut self,
        mut mesh: Mesh,
        rect: Rect,
        params: &Params,
        values: &Values,
        batch: usize,
    ) -> Result<(Mesh, Round, u64), Vec<Point>> {
        let mut replay = Replay::new(values, batch, &mesh);
        let mut frontier = Frontier { values, mesh: None };
        match resume(&mut mesh, &mut replay, params, Floors::of_rect(rect), &mut frontier) {
            Ok(round) if replay.asked.is_empty() => Ok((mesh, round, replay.used)),
            _ => {
                self.frontier = frontier.mesh;
                Err(replay.asked)
            }
        }
    }
}

/// Watches a replay for the first edge it chooses whose midpoint is untold, and keeps the
/// mesh as it stood then.
struct Frontier<'v> {
    values: &'v Values,
    mesh: Option<Mesh>,
}

impl Observer for Frontier<'_> {
    fn selected(&mut self, mesh: &Mesh, a: u32, b: u32) {
        if self.mesh.is_none() && self.values.get(mesh.point(a).midpoint(mesh.point(b))).is_none() {
            self.mesh = Some(mesh.clone());
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

impl<'v> Replay<'v> {
    /// A replay over `values` that asks at most `batch` points, from `mesh`.
    fn new(values: &'v Values, batch: usize, mesh: &Mesh) -> Self {
        Replay {
            values,
            asked: Vec::new(),
            seen: HashSet::new(),
            batch: batch.max(1),
            used: mesh.num_vertices() as u64,
        }
    }
}

impl Field for Replay<'_> {
    type Error = Full;

    fn midpoint(&mut self, a: Vertex, b: Vertex, m: Point) -> Result<f64, Full> {
        self.predicted_midpoint(a, b, m, 0.5 * (a.z + b.z))
    }

    fn predicted_midpoint(&mut self, _a: Vertex, _b: Vertex, m: Point, stand_in: f64) -> Result<f64, Full> {
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
    /// Never called: [`next`] refuses criterion `error`, the only one that estimates
    /// triangles.
    fn estimate(&mut self, _mesh: &Mesh, _t: u32, _known: [Option<f64>; 3]) -> Result<(f64, [f64; 3]), Full> {
        unreachable!("criteria variation and curvature estimate no triangle")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::{Method, refine};
    use proptest::prelude::*;

    /// Plays the caller: asks until done, telling F at every point asked, with one [`Asker`]
    /// so each replay starts at the last one's frontier.
    fn played(
        f: impl Fn(f64, f64) -> f64,
        rect: Rect,
        params: &Params,
        batch: usize,
    ) -> (Refinement, usize, usize) {
        let (mut values, mut asked, mut asker) = (Values::new(), 0, Asker::default());
        loop {
            match asker.next(rect, params, &values, batch).unwrap() {
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
        with(max_vertices, method, Criterion::Variation)
    }

    fn with(max_vertices: usize, method: Method, criterion: Criterion) -> Params {
        Params::builder(max_vertices).criterion(criterion).method(method).build().unwrap()
    }

    /// The same mesh and the same stats but the clock's.
    fn same_mesh(a: &Refinement, b: &Refinement) {
        assert_eq!(a.mesh.vertices(), b.mesh.vertices());
        assert_eq!(a.mesh.triangles().collect::<Vec<_>>(), b.mesh.triangles().collect::<Vec<_>>());
        let (s, t) = (&a.stats, &b.stats);
        assert_eq!(
            (s.flips, s.retired_edges, s.stop, s.delaunay),
            (t.flips, t.retired_edges, t.stop, t.delaunay)
        );
        assert_eq!(format!("{:?}", s.history), format!("{:?}", t.history));
    }

    #[test]
    fn one_point_a_batch_asks_exactly_the_points_of_the_sequential_run() {
        let f = |x: f64, y: f64| (3.0 * x).sin() * (2.0 * y).cos() + x * y;
        let rect = Rect::new(-1.0, 2.0, 0.0, 1.5).unwrap();
        for criterion in [Criterion::Variation, Criterion::Curvature] {
            let params = with(300, Method::SemiRecursive, criterion);
            let (asked, points, unused) = played(f, rect, &params, 1);
            let direct = refine(&f, rect, &params, &mut ()).unwrap();
            same_mesh(&asked, &direct);
            assert_eq!((points, unused), (300, 0), "one evaluation a vertex, none wasted");
            assert_eq!(asked.stats.evaluations, direct.stats.evaluations);
            // Fifty at a time guesses ahead, and some guesses miss: the same mesh, points unused.
            let (ahead, points, unused) = played(f, rect, &params, 50);
            same_mesh(&ahead, &direct);
            assert!(unused > 0 && points == 300 + unused, "{criterion}: {points} asked, {unused} unused");
        }
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
            curvature in any::<bool>(),
        ) {
            let f = move |x: f64, y: f64| (a * x).sin() + b * x * y * y;
            let rect = Rect::new(0.0, 1.0, -1.0, 1.0).unwrap();
            let method = if recursive { Method::Recursive } else { Method::SemiRecursive };
            let criterion = if curvature { Criterion::Curvature } else { Criterion::Variation };
            let params = with(200, method, criterion);
            let (asked, points, unused) = played(f, rect, &params, batch);
            same_mesh(&asked, &refine(&f, rect, &params, &mut ()).unwrap());
            prop_assert_eq!(points as u64, asked.stats.evaluations + unused as u64);
        }
    }
}
