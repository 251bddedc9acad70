"""The agents' error for files it cannot use (its own module: the policies and the file
readers both raise it, and the readers import the policies)."""

from __future__ import annotations

__all__ = ["PolicyFileError"]


class PolicyFileError(ValueError):
    """A model, run record or replay buffer file that cannot be used; the message names it."""
