"""Atomic file writes: a temporary file beside the target, then a rename over it.

A reader never sees a half-written file, and a crash mid-write leaves the old file intact.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

#: Suffix of the temporary files of :func:`atomic_open` (``.<name>.<uuid>.tmp``).
TMP_SUFFIX = ".tmp"


def remove_stale_temporaries(folder: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files that an interrupted :func:`atomic_open` left in ``folder``
    (a killed process cannot clean up); returns those removed."""
    stale = sorted(Path(folder).glob(f".*.*{TMP_SUFFIX}"))
    for path in stale:
        path.unlink(missing_ok=True)
    return stale


def _sync_folder(folder: Path) -> None:
    """fsync ``folder``, so that a rename in it survives a power loss (POSIX; where a folder
    cannot be opened or synced, e.g. on Windows or some network file systems, the rename is
    still atomic, only its durability is the file system's)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO]:
    """Open a temporary file next to ``path`` for writing (``mode`` "w" text or "wb" binary);
    on a clean exit it is flushed, synced and renamed over ``path`` (and the folder synced, so
    the rename is durable), otherwise removed."""
    if mode not in ("w", "wb"):
        raise ValueError(f"mode={mode!r} must be 'w' or 'wb'")
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}{TMP_SUFFIX}")
    try:
        with open(tmp, mode.replace("w", "x"), **({} if "b" in mode else
                                                  {"encoding": "utf-8", "newline": ""})) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        _sync_folder(path.parent)
    finally:
        tmp.unlink(missing_ok=True)


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically, creating parent folders."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "w") as f:
        f.write(text)


def save_figure_atomic(figure: Any, path: str | os.PathLike[str], **savefig: Any) -> None:
    """Save a matplotlib ``figure`` to ``path`` atomically, in the format its suffix names
    (``.png``, ``.pdf``, ...), creating parent folders; ``savefig`` goes to
    ``figure.savefig`` (e.g. ``dpi``)."""
    path = Path(path)
    if not path.suffix:
        raise ValueError(f"figure path {path}: give a suffix naming the format (e.g. .png)")
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "wb") as f:
        figure.savefig(f, format=path.suffix[1:], **savefig)


def folder_problem(folder: str | os.PathLike[str]) -> str | None:
    """Why files cannot be written into ``folder`` (created if missing), or None when they
    can: checked by creating and removing a temporary file there, so that a command can refuse
    an unusable output folder before its work rather than lose the work at the end."""
    import tempfile
    folder = Path(folder)
    for part in (folder, *folder.parents):       # the nearest existing part must be a folder
        if part.exists():
            if not part.is_dir():
                return f"{part} is a file, not a folder"
            break
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError as exc:
        return exc.strerror or str(exc)
    return None
