//! How a request another replica kept is read, for a takeover.

use super::peers::KeptRequest;
use crate::spec::{JobKeys, JobSpec};

/// How a request another replica kept is read when replicas share: the server's own parsing
/// of a request body (its content types are the HTTP layer's), given to the registry by the
/// caller.
pub trait RequestParser: Send + Sync + 'static {
    /// Reads a request another replica kept, as if a client had just sent it here.
    fn parse(
        &self,
        request: KeptRequest,
    ) -> futures_util::future::BoxFuture<'static, Result<(JobKeys, JobSpec), String>>;
}
