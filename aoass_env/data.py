"""Where the shipped data lives: ``maps/``, ``configs/`` and ``checkpoints/``.

In a checkout (and an editable install) they are the repository's top-level folders; a built
wheel carries copies of them as package data, ``aoass_env/_data/<folder>`` (setup.py), found
with :mod:`importlib.resources`.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

__all__ = ["SHIPPED", "shipped_dir"]

#: The shipped folders.
SHIPPED = ("maps", "configs", "checkpoints")


def shipped_dir(name: str) -> Path:
    """The folder of the shipped ``name`` (one of :data:`SHIPPED`): the installed package's
    copy when there is one, else the checkout's; ValueError naming ``name`` otherwise."""
    if name not in SHIPPED:
        raise ValueError(f"name={name!r} must be one of {SHIPPED}")
    packaged = files("aoass_env") / "_data" / name
    if packaged.is_dir():
        return Path(str(packaged))
    return Path(__file__).resolve().parents[1] / name
