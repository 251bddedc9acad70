"""Where independent pieces of work run: local processes (the default) or a Ray cluster; and
:func:`deliver_interrupts`, which keeps the first Ctrl-C from being lost in a physics callback.

A backend maps a function over items and yields ``(item, result, None)`` or
``(item, None, traceback)`` as each piece finishes, in completion order. The caller (this
process) consumes the results and stays the only writer of its output files; only the work
moves. ``evaluate.py`` runs its episodes through a backend, ``train.py --seeds`` its training
runs (docs/cluster.md).

* :class:`LocalBackend`: ``workers`` processes of a
  :class:`concurrent.futures.ProcessPoolExecutor`, or this process alone when ``workers`` is 1;
  a worker that dies fails the items not yet done (reported, so a sweep ends and resumes).
* :class:`RayBackend`: one Ray task per item on a cluster (``address``) or on a local Ray
  instance started here. A task that raises, or whose worker dies, is retried ``retries``
  times by Ray; then its failure is yielded like any other.

Ray is an optional dependency (``pip install -e '.[ray]'``), imported only by
:func:`require_ray`.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import os
import re
import signal
import threading
import traceback
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from types import FrameType
from typing import Any, Protocol, TypeVar

import torch

from aoass_env.validators import integer, one_line, positive

__all__ = ["BACKENDS", "Backend", "BackendError", "LocalBackend", "RayBackend",
           "add_backend_arguments", "deliver_interrupts", "init_ray", "make_backend",
           "require_ray", "set_threads"]

T = TypeVar("T")
R = TypeVar("R")

#: Names accepted by ``--backend``.
BACKENDS = ("local", "ray")
#: How to install the optional Ray dependency.
RAY_INSTALL = "pip install -e '.[ray]'"
#: Ray retries of a failed task (an exception, or its worker died) before it is reported.
RAY_RETRIES = 2

#: Seconds to wait for cancelled Ray tasks to stop when the caller stops early.
_CANCEL_WAIT = 10.0
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


class BackendError(ValueError):
    """A backend that cannot be used: Ray missing, a cluster that cannot be reached, bad
    settings."""


class Backend(Protocol):
    """Runs ``fn`` on each item; yields ``(item, result, None)`` or ``(item, None, traceback)``
    in completion order. Closing the iterator early stops the outstanding work."""

    @property
    def description(self) -> str:
        """Where the work runs, for reports."""

    def run(self, fn: Callable[[T], R], items: Sequence[T]
            ) -> Iterator[tuple[T, R | None, str | None]]: ...


def set_threads(threads: int) -> None:
    """Torch threads of this process (small networks: one each, the processes share cores)."""
    torch.set_num_threads(threads)


#: What an item of a local worker process that died is reported with.
_DEAD_WORKER = ("a local worker process died (killed, out of memory, or a crash in native code) "
                "while this item ran or waited; run it again")


def _attempt(fn: Callable[[T], R], item: T) -> tuple[T, R | None, str | None]:
    """``(item, fn(item), None)``, or ``(item, None, traceback)`` when ``fn`` raised."""
    try:
        return item, fn(item), None
    except Exception:  # one failed item is reported; the others go on
        return item, None, traceback.format_exc()


class LocalBackend:
    """``workers`` processes on this machine, each with ``threads`` torch threads; with one
    worker (or one item) the items run one after another in this process, which keeps its
    own thread setting.

    Raises:
        BackendError: ``workers`` or ``threads`` below 1.
    """

    def __init__(self, workers: int = 1, *, threads: int = 1) -> None:
        self.workers = integer("workers", workers, low=1, error=BackendError)
        self.threads = integer("threads", threads, low=1, error=BackendError)

    @property
    def description(self) -> str:
        return (f"{self.workers} local worker process(es)" if self.workers > 1
                else "this process")

    def run(self, fn: Callable[[T], R], items: Sequence[T]
            ) -> Iterator[tuple[T, R | None, str | None]]:
        """Each item's result in completion order. A worker process that dies (killed, out of
        memory, a crash in native code) fails the items it held and those not yet done, each
        reported with that reason (``multiprocessing.Pool`` lost the item it held and waited
        for it forever)."""
        guarded = functools.partial(_attempt, fn)
        if self.workers == 1 or len(items) <= 1:
            yield from map(guarded, items)
            return
        pool = ProcessPoolExecutor(min(self.workers, len(items)), initializer=set_threads,
                                   initargs=(self.threads,))
        try:
            futures = {pool.submit(guarded, item): item for item in items}
            for future in as_completed(futures):
                try:
                    yield future.result()
                except BrokenProcessPool:
                    yield futures[future], None, _DEAD_WORKER
        finally:
            processes = list(getattr(pool, "_processes", {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for process in processes:      # stop the outstanding work now, as Pool.terminate
                process.terminate()
            for process in processes:
                process.join()


def require_ray() -> Any:
    """The ``ray`` module.

    Raises:
        BackendError: Ray is not installed; the message says how to install it.
    """
    try:
        import ray
    except ImportError:
        raise BackendError(f"--backend ray needs Ray: {RAY_INSTALL}") from None
    return ray


def init_ray(address: str | None = None, num_cpus: int | None = None) -> None:
    """Connect this process to Ray, unless it already is (then nothing changes).

    Args:
        address: a running cluster: ``auto`` (the one started on this machine with
            ``ray start``) or ``HOST:PORT`` of its head. None: ``$RAY_ADDRESS`` when set (as in
            ``ray job submit``), else a new local Ray instance of ``num_cpus`` CPUs (default: all
            cores), stopped when this process exits.
        num_cpus: CPUs of a new local instance; not allowed with a cluster ``address``.

    Raises:
        BackendError: Ray is missing, ``num_cpus`` is given with an address or is below 1, or
            the cluster cannot be reached.
    """
    ray = require_ray()
    if ray.is_initialized():
        return
    address = address or os.environ.get("RAY_ADDRESS") or None
    if num_cpus is not None and (address is not None or num_cpus < 1):
        raise BackendError(f"num_cpus={num_cpus} sets the size of a new local Ray instance: "
                           f"at least 1, and only without an address (got {address!r})")
    try:
        if address is None:
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False)
        else:
            ray.init(address=address)
    except ConnectionError as exc:
        raise BackendError(f"cannot reach the Ray cluster at --address {address}: "
                           f"{one_line(exc)}; start one with `ray start --head`, or leave out "
                           f"--address to start a local Ray instance") from None
    except ValueError as exc:   # Ray's own text does not say where the address came from
        raise BackendError(f"--address {address!r} (or $RAY_ADDRESS) is not a Ray cluster "
                           f"address ({one_line(exc)}): give 'auto' or HOST:PORT") from None


def _ray_task(fn: Callable[[T], R], item: T, threads: int) -> R:
    """The body of a Ray task: ``fn(item)`` with ``threads`` torch threads. Raises what ``fn``
    raises, so that Ray retries it."""
    set_threads(threads)
    return fn(item)


class RayBackend:
    """One Ray task per item, each with ``task_cpus`` CPUs and ``threads`` torch threads.

    Connects to Ray on construction (:func:`init_ray` with ``address`` and ``num_cpus``). A
    task that raises, or whose worker process or node dies, is run again up to ``retries``
    times; after that its last error is yielded as the item's failure. Items, ``fn`` and the
    results travel by pickle: ``fn`` must be importable on the workers (the package installed
    there) and the paths it opens must exist there.

    Raises:
        BackendError: Ray is missing or unreachable, or a setting is out of range.
    """

    def __init__(self, address: str | None = None, *, num_cpus: int | None = None,
                 retries: int = RAY_RETRIES, task_cpus: float = 1.0, threads: int = 1) -> None:
        retries = integer("retries", retries, low=0, error=BackendError)
        task_cpus = positive("task_cpus", task_cpus, "CPUs", error=BackendError)
        threads = integer("threads", threads, low=1, error=BackendError)
        init_ray(address, num_cpus)
        self.retries = retries
        self.task_cpus = task_cpus
        self.threads = threads

    @property
    def description(self) -> str:
        ray = require_ray()
        cpus = ray.cluster_resources().get("CPU", 0)
        nodes = sum(1 for node in ray.nodes() if node.get("Alive"))
        return f"Ray ({cpus:g} CPU(s) on {nodes} node(s))"

    def _failure(self, exc: BaseException) -> str:
        """The report of a task that failed on every attempt: the last attempt's traceback
        (Ray's text, which names the worker's pid and node)."""
        return (f"failed on Ray after {self.retries + 1} attempt(s); the last one "
                f"({type(exc).__name__}):\n" + _ANSI.sub("", str(exc)))

    def run(self, fn: Callable[[T], R], items: Sequence[T]
            ) -> Iterator[tuple[T, R | None, str | None]]:
        ray = require_ray()
        task = ray.remote(_ray_task).options(num_cpus=self.task_cpus, max_retries=self.retries,
                                             retry_exceptions=True)
        fn_ref = ray.put(fn)
        pending = {task.remote(fn_ref, item, self.threads): item for item in items}
        try:
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    item = pending.pop(ref)
                    try:
                        outcome = (item, ray.get(ref), None)
                    except Exception as exc:  # the task failed on every attempt
                        outcome = (item, None, self._failure(exc))
                    yield outcome
        finally:
            if pending:                  # stopped early (Ctrl-C, an error in the caller)
                for ref in pending:
                    ray.cancel(ref)
                # let the cancellations settle: Ray can abort when this process exits while
                # they are in flight
                ray.wait(list(pending), num_returns=len(pending), timeout=_CANCEL_WAIT)


def make_backend(name: str, *, workers: int | None = None, address: str | None = None,
                 threads: int = 1, task_cpus: float = 1.0, retries: int = RAY_RETRIES
                 ) -> LocalBackend | RayBackend:
    """The backend called ``name`` (``--backend``): ``local`` with ``workers`` processes
    (default: all cores), or ``ray`` at ``address`` (``workers``: the CPUs of a new local Ray
    instance; default all cores).

    Raises:
        BackendError: an unknown name, ``--address`` with the local backend, ``--workers``
            with a cluster address, Ray missing or unreachable.
    """
    if name not in BACKENDS:
        raise BackendError(f"--backend {name!r} is not one of {', '.join(BACKENDS)}")
    if name == "local":
        if address is not None:
            raise BackendError("--address names a Ray cluster; it needs --backend ray")
        # 0 is refused by LocalBackend (it read as "not given": every core)
        return LocalBackend((os.cpu_count() or 1) if workers is None else workers,
                            threads=threads)
    if workers is not None and (address or os.environ.get("RAY_ADDRESS")):
        raise BackendError("--workers sets the CPUs of a local Ray instance; a cluster "
                           "(--address or $RAY_ADDRESS) runs one task per CPU it has")
    return RayBackend(address, num_cpus=workers, retries=retries, task_cpus=task_cpus,
                      threads=threads)


def add_backend_arguments(parser: argparse.ArgumentParser, unit: str, local: str) -> None:
    """Add ``--backend`` and ``--address`` to ``parser``; for the help, ``unit`` names what one
    Ray task runs and ``local`` says how the local backend runs them."""
    parser.add_argument("--backend", choices=BACKENDS, default="local",
                        help=f"local (default): {local}; ray: one Ray task per {unit} "
                             f"(docs/cluster.md)")
    parser.add_argument("--address", metavar="ADDR",
                        help="with --backend ray: the cluster, 'auto' or HOST:PORT (default: "
                             "$RAY_ADDRESS, else a new local Ray instance)")


# ---------------------------------------------------------------------------- interrupts
# pymunk calls Python callbacks (the anchor's velocity function) from C through cffi, which
# prints and swallows any exception raised in them: a KeyboardInterrupt that lands there is lost
# and the run goes on. Within deliver_interrupts(), a Ctrl-C that arrives inside such a callback
# is held and raised at the first moment outside it.

#: The source file whose frames mean "pymunk called Python back from C".
_CALLBACK_FILE = ("pymunk", "_callbacks.py")
#: How soon (s) a held Ctrl-C is tried again.
RETRY_SECONDS = 0.005


def _in_callback(frame: FrameType | None) -> bool:
    while frame is not None:
        if Path(frame.f_code.co_filename).parts[-2:] == _CALLBACK_FILE:
            return True
        frame = frame.f_back
    return False


class _HeldInterrupt:
    """The state of :func:`deliver_interrupts`: whether a Ctrl-C is held, the caller's SIGALRM
    handler and the caller's real-time timer it set aside to retry it."""

    def __init__(self, caller_alarm: Any) -> None:
        self.held = False
        self.caller_alarm = caller_alarm
        self.caller_timer = (0.0, 0.0)

    def hold(self) -> None:
        """Hold the Ctrl-C and retry it in :data:`RETRY_SECONDS` on the real-time timer,
        setting the caller's timer aside (once) until then."""
        timer = signal.setitimer(signal.ITIMER_REAL, RETRY_SECONDS)
        if not self.held:
            self.held, self.caller_timer = True, timer

    def release(self) -> None:
        """Forget the held Ctrl-C; the caller's timer runs on from where it was set aside."""
        if self.held:
            self.held = False
            signal.setitimer(signal.ITIMER_REAL, *self.caller_timer)

    def on_interrupt(self, signum: int, frame: FrameType | None) -> None:
        if _in_callback(frame):      # raised here, cffi would swallow it: try again shortly
            self.hold()
            return
        self.release()
        raise KeyboardInterrupt

    def on_alarm(self, signum: int, frame: FrameType | None) -> None:
        if self.held:
            self.on_interrupt(signum, frame)
            return
        # the caller's own alarm: its handler, as without deliver_interrupts
        caller = self.caller_alarm
        if callable(caller):
            caller(signum, frame)
        elif caller == signal.SIG_DFL:
            signal.signal(signal.SIGALRM, signal.SIG_DFL)
            signal.raise_signal(signal.SIGALRM)


@contextlib.contextmanager
def deliver_interrupts() -> Iterator[None]:
    """Within: the first Ctrl-C raises ``KeyboardInterrupt`` in the main thread even when it
    arrives inside a pymunk callback (it is then raised a few milliseconds later, outside it,
    on the real-time timer; a timer of the caller's is set aside meanwhile and its SIGALRM
    goes to the caller's handler otherwise). Does nothing outside the main thread or when
    SIGINT is not Python's default handler (e.g. ignored)."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    state = _HeldInterrupt(signal.getsignal(signal.SIGALRM))
    signal.signal(signal.SIGALRM, state.on_alarm)
    signal.signal(signal.SIGINT, state.on_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        state.release()
        caller = state.caller_alarm       # None: a handler not set from Python
        signal.signal(signal.SIGALRM, signal.SIG_DFL if caller is None else caller)
