"""Ctrl-C that is never lost inside a physics callback.

pymunk calls Python callbacks (the anchor's velocity function) from C through cffi, which prints
and swallows any exception raised in them: a ``KeyboardInterrupt`` that lands there is lost and
the run goes on. Within :func:`deliver_interrupts`, a Ctrl-C that arrives inside such a callback
is held and raised at the first moment outside it.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from pathlib import Path
from types import FrameType

import pymunk

__all__ = ["deliver_interrupts"]

#: Source files whose frames mean "Python called back from C": an exception there is swallowed.
_CALLBACK_FILES = frozenset({str(Path(pymunk.__file__).with_name("_callbacks.py"))})
#: How soon (s) a held Ctrl-C is tried again.
RETRY_SECONDS = 0.005


def _in_callback(frame: FrameType | None) -> bool:
    while frame is not None:
        if frame.f_code.co_filename in _CALLBACK_FILES:
            return True
        frame = frame.f_back
    return False


def _handler(signum: int, frame: FrameType | None) -> None:
    if _in_callback(frame):          # raised here, cffi would swallow it: try again shortly
        signal.setitimer(signal.ITIMER_REAL, RETRY_SECONDS)
        return
    signal.setitimer(signal.ITIMER_REAL, 0)
    raise KeyboardInterrupt


@contextlib.contextmanager
def deliver_interrupts() -> Iterator[None]:
    """Within: the first Ctrl-C raises ``KeyboardInterrupt`` in the main thread even when it
    arrives inside a pymunk callback (it is then raised a few milliseconds later, outside it).
    Does nothing outside the main thread or when SIGINT is not Python's default handler (e.g.
    ignored)."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    old_alarm = signal.signal(signal.SIGALRM, _handler)
    signal.signal(signal.SIGINT, _handler)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGALRM, old_alarm)
