"""The combined energy's landmark prior, computed for every live session of a server in one child process.

On a thread of the server the prior (NO17's descriptor parts and two solves: 1-2 s of a core at 28k vertices)
took the GIL in thousands of short steps beside the clicks' own work, and at a person's pace it was most of
click-to-texture's tail in ``benchmarks/bench_ui_latency.py``. A child process at nice :data:`PRIOR_NICE` shares
no GIL with the server, and the scheduler favours the clicks.

:meth:`PriorProcess.landmark_maps` is a drop-in for :func:`curvefm.fmap.landmark_maps` (the solver's
``prior_maps``). The child keeps the last :data:`BASES_KEPT` bases it was sent, by content, and the descriptor
parts cached beside :func:`~curvefm.fmap.landmark_maps`, so a session's bases cross the pipe once (the first
request for one it lacks is answered "missing" and sent again with it) and a request carries only the landmark
pairs. While the child works the parent asks the request's ``wanted`` every :data:`POLL_S` and sends a cancel
when it turns false; the child looks for one before each step and gives up (:class:`NoLongerWanted`).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import threading
from collections.abc import Callable
from multiprocessing.connection import Connection

import numpy as np

from curvefm.cache import LRU
from curvefm.errors import CurvefmError
from curvefm.fmap import FunctionalMaps, landmark_maps
from curvefm.fmap.landmark_prior import NoLongerWanted
from curvefm.fmap.solver import basis_digest
from curvefm.spectral import Basis

PRIOR_NICE = 10
POLL_S = 0.02
BASES_KEPT = 8
STOP_WAIT_S = 5.0

log = logging.getLogger(__name__)


class PriorUnavailable(CurvefmError):
    """The child process failed or stopped: the maps are solved without a prior until the next request."""

    def __init__(self, reason: str):
        super().__init__(f"the landmark prior's process gave no maps: {reason}")


class PriorProcess:
    """One child process computing landmark priors, started on first use and again after it stops. Requests from
    several threads are served one at a time."""

    def __init__(self):
        self._lock = threading.Lock()
        self._process: multiprocessing.process.BaseProcess | None = None
        self._connection: Connection | None = None
        self.bases_sent = 0  # over the process's lifetime: each session's bases should be sent once

    def landmark_maps(self, basis_M: Basis, basis_N: Basis, landmarks: np.ndarray,
                      wanted: Callable[[], bool] = lambda: True) -> FunctionalMaps:  # fmt: skip
        """What :func:`curvefm.fmap.landmark_maps` returns for these arguments, computed in the child."""
        with self._lock:
            try:
                return self._maps(basis_M, basis_N, np.asarray(landmarks, dtype=np.int64), wanted)
            except (EOFError, OSError) as error:  # the child died (killed, out of memory) or its pipe broke
                self._stop()
                raise PriorUnavailable(type(error).__name__) from error

    def close(self) -> None:
        with self._lock:
            self._stop()

    @property
    def pid(self) -> int | None:
        return self._process.pid if self._process is not None and self._process.is_alive() else None

    def _maps(self, basis_M: Basis, basis_N: Basis, landmarks: np.ndarray, wanted: Callable[[], bool]):
        digests = (basis_digest(basis_M), basis_digest(basis_N))
        reply = self._ask(("maps", digests, landmarks), wanted)
        if reply[0] == "missing":
            for digest, basis in dict(zip(digests, (basis_M, basis_N), strict=True)).items():
                if digest in reply[1]:
                    self._connected().send(("basis", digest, basis))
                    self.bases_sent += 1
            reply = self._ask(("maps", digests, landmarks), wanted)
        if reply[0] == "superseded":
            raise NoLongerWanted
        if reply[0] == "failed":
            raise PriorUnavailable(reply[1])
        return reply[1]

    def _ask(self, request: tuple, wanted: Callable[[], bool]) -> tuple:
        connection = self._connected()
        connection.send(request)
        cancelled = False
        while not connection.poll(POLL_S):
            if not cancelled and not wanted():
                connection.send(("cancel",))
                cancelled = True
            if not self._process.is_alive():
                raise EOFError
        return connection.recv()

    def _connected(self) -> Connection:
        if self._connection is None:
            # spawn, not fork: a fork of the threaded server could inherit a lock held by another thread
            context = multiprocessing.get_context("spawn")
            self._connection, child_end = context.Pipe()
            self._process = context.Process(target=serve, args=(child_end,), name="curvefm-priors", daemon=True)
            self._process.start()
            child_end.close()
        return self._connection

    def _stop(self) -> None:
        if self._connection is None:
            return
        self._connection.close()  # the child's recv ends and it returns
        self._process.join(STOP_WAIT_S)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()
        self._connection = self._process = None


def serve(connection: Connection) -> None:
    """The child's loop: keep the bases it is sent, answer each request for maps, until the pipe closes."""
    _lower_priority()
    bases: LRU[Basis] = LRU(BASES_KEPT)
    while True:
        try:
            message = connection.recv()
        except (EOFError, OSError):
            return
        if message[0] == "basis":
            bases.put(message[1], message[2])
        elif message[0] == "maps":
            connection.send(_answer(bases, connection, *message[1:]))
        # else a cancel that came after its request had been answered: nothing to do


def _answer(bases: LRU[Basis], connection: Connection, digests: tuple, landmarks: np.ndarray) -> tuple:
    missing = [digest for digest in digests if bases.peek(digest) is None]
    if missing:
        return ("missing", missing)
    basis_M, basis_N = (bases.peek(digest) for digest in digests)
    try:
        # any message while it works is the parent's cancel (it sends nothing else before this answer)
        return ("maps", landmark_maps(basis_M, basis_N, landmarks, wanted=lambda: not connection.poll()))
    except NoLongerWanted:
        return ("superseded",)
    except Exception as error:  # noqa: BLE001  (the server goes on without a prior; the reason is logged there)
        return ("failed", str(error) if isinstance(error, CurvefmError) else type(error).__name__)


def _lower_priority() -> None:
    """Every thread of this process :data:`PRIOR_NICE` nicer than it started (Linux sets it thread by thread, and
    the BLAS library may have started threads of its own before this runs)."""
    try:
        for thread in map(int, os.listdir("/proc/self/task")):
            os.setpriority(os.PRIO_PROCESS, thread, min(19, os.getpriority(os.PRIO_PROCESS, thread) + PRIOR_NICE))
    except (AttributeError, OSError):  # not Linux
        os.nice(PRIOR_NICE)
