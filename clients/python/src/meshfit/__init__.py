"""A client for the meshfit HTTP API."""

from .client import Client, Job, MeshfitError, Result

__all__ = ["Client", "Job", "MeshfitError", "Result"]
