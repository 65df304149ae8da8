//! Why a job failed, as data: what the replica that ran it stores for the others, and what
//! the server renders for every client, whichever replica it asks. One shape on both paths,
//! so a failure reads the same everywhere.

use crate::geom::ConstrainedError;
use crate::refine::RefineError;
use crate::solve::SolveError;
use serde::{Deserialize, Serialize};

/// What kind of failure: who must act on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Cause {
    /// F is not finite where the mesh needs it: the client's function.
    NonFiniteValue,
    /// The boundary value problem is invalid where the solver sampled it: the client's problem.
    InvalidProblem,
    /// Something went wrong inside a server: the operator's.
    Internal,
}

/// A job's failure, in the terms clients are told it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Failure {
    /// What kind.
    pub cause: Cause,
    /// What went wrong, in a sentence (an internal one is for the logs, never for clients).
    pub message: String,
    /// The request member at fault, as messages name it (`k`, `regions`, `boundary`).
    pub field: Option<String>,
    /// Where in the domain, when known (always finite).
    pub point: Option<[f64; 2]>,
}

impl Failure {
    /// An internal failure.
    pub fn internal(message: impl Into<String>) -> Self {
        Self { cause: Cause::Internal, message: message.into(), field: None, point: None }
    }

    /// A failure on the input, at (x, y) if that is a point.
    fn input(cause: Cause, message: String, field: Option<&str>, x: f64, y: f64) -> Self {
        let point = (x.is_finite() && y.is_finite()).then_some([x, y]);
        Self { cause, message, field: field.map(str::to_owned), point }
    }
}

impl From<&RefineError> for Failure {
    fn from(e: &RefineError) -> Self {
        let RefineError::NonFinite { point, .. } = e;
        Failure::input(Cause::NonFiniteValue, e.to_string(), None, point.x, point.y)
    }
}

impl From<&SolveError> for Failure {
    fn from(e: &SolveError) -> Self {
        let (field, x, y) = match *e {
            SolveError::InvalidK { x, y, .. } => ("k", x, y),
            SolveError::NonFiniteF { x, y, .. } | SolveError::Overflow { x, y, .. } => ("f", x, y),
            SolveError::NonFiniteG { x, y, .. } => ("g", x, y),
            SolveError::Regions(ConstrainedError::BadPoint { x, y }) => ("regions", x, y),
            SolveError::Regions(_) => ("regions", f64::NAN, f64::NAN),
            SolveError::Unmatched { x, y } => ("boundary", x, y),
            // A mesh the server made that the solver cannot use: the server's fault.
            SolveError::DegenerateTriangle { .. }
            | SolveError::NotPositiveDefinite { .. }
            | SolveError::Factorisation(_) => return Failure::internal(e.to_string()),
        };
        Failure::input(Cause::InvalidProblem, e.to_string(), Some(field), x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;

    /// Every failure survives the store's encoding as it was, non-finite values included
    /// (they travel in the message; the point is dropped rather than written as null).
    #[test]
    fn failures_read_back_as_written() {
        let failures = [
            Failure::from(&RefineError::NonFinite { point: Point::new(0.5, 1.0), value: f64::NAN }),
            Failure::from(&SolveError::InvalidK { x: 0.25, y: 0.75, value: f64::NEG_INFINITY, triangle: 3 }),
            Failure::from(&SolveError::Regions(ConstrainedError::Budget { budget: 10 })),
            Failure::from(&SolveError::Unmatched { x: 0.0, y: f64::NAN }),
            Failure::from(&SolveError::NotPositiveDefinite { pivot: 2, unknowns: 9 }),
            Failure::internal("the refinement panicked"),
        ];
        for failure in failures {
            let stored = serde_json::to_string(&failure).unwrap();
            let read: Failure = serde_json::from_str(&stored).unwrap();
            assert_eq!(read, failure, "{stored}");
        }
    }

    #[test]
    fn the_field_and_point_name_where_the_input_is_wrong() {
        let f = Failure::from(&SolveError::NonFiniteG { x: 1.0, y: 0.0, value: f64::INFINITY, vertex: 4 });
        assert_eq!(
            (f.cause, f.field.as_deref(), f.point),
            (Cause::InvalidProblem, Some("g"), Some([1.0, 0.0]))
        );
        assert!(f.message.contains("inf"), "{}", f.message);
        let f = Failure::from(&SolveError::Regions(ConstrainedError::Invalid("x".into())));
        assert_eq!((f.field.as_deref(), f.point), (Some("regions"), None));
        let f = Failure::from(&SolveError::DegenerateTriangle { triangle: 1, area: -1.0 });
        assert_eq!(f.cause, Cause::Internal);
    }
}
