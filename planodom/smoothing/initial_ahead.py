"""The batch's windowed initial guess computed ahead, in a forked child process
(``smoothing.batch_initial_concurrent``, issue 14).

Why a process: with ``batch_initial`` "windowed" the batch first runs the whole fixed-lag
smoother (gtsam's iSAM2, about 9 s of the 2 000-epoch lap's 60 s) and only then builds its
own graph epoch by epoch (17 s), although building epoch ``k`` reads the guess of epochs
``<= k`` only (:meth:`.GraphBuilder._add_pose` seeds ``X(k)`` with it, and loop closure
predicts from the poses seeded so far). A fixed-lag pose is final once it has left the
window: :meth:`.WindowedSmoother.add_epoch` updates only the epochs still in it. So the
smoother can run ahead while the graph is built, each pose handed over as soon as it is
final. Threads would not overlap: gtsam's Python bindings keep the GIL and the smoother's
factors call back into Python. ``fork`` shares the inputs without copying or pickling them;
the child computes what :func:`.windowed.smooth_windowed` computes, the same operations on
the same numbers, so the poses are the same bits.
"""

from __future__ import annotations

import multiprocessing
import os
import resource
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from multiprocessing.connection import Connection

import numpy as np

from planodom.config import PlanodomConfig
from planodom.errors import PlanodomError
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose


def _run(
    conn: Connection,
    epochs_planes: Sequence[Sequence[Plane]],
    relative_poses: Sequence[RelativePose],
    config: PlanodomConfig,
) -> None:
    """The child: :func:`.windowed.smooth_windowed`'s loop, sending ``("poses", list)``
    whenever poses leave the window, then the rest of them and ``("done", (QR fallback
    epochs, indefinite marginals, CPU s))``; ``("error", exception)`` if it fails."""
    from planodom.smoothing.batch import group_by_epoch  # (batch imports this module)
    from planodom.smoothing.windowed import WindowedSmoother

    try:
        smoother = WindowedSmoother(config)
        lag = smoother.config.window - 1
        by_epoch = group_by_epoch(relative_poses, len(epochs_planes))
        sent = 0
        for k, planes in enumerate(epochs_planes):
            smoother.add_epoch(planes, by_epoch[k])
            final = max(0, k - lag)  # the oldest epoch still in the window
            if final > sent:
                conn.send(("poses", smoother.poses[sent:final]))
                sent = final
        result = smoother.result()
        conn.send(("poses", list(result.poses[sent:])))
        usage = resource.getrusage(resource.RUSAGE_SELF)
        cpu = usage.ru_utime + usage.ru_stime
        conn.send(("done", (result.qr_fallback_epochs, result.indefinite_marginals, cpu)))
    except BaseException as exc:  # handed to the parent, which raises it
        conn.send(("error", exc))
    finally:
        conn.close()


class GuessAhead:
    """The windowed guess's (E, 4, 4) poses as they arrive from the child: ``guess[k]``
    waits until pose ``k`` is final (``T_world_first @`` it when given, as the batch's
    inline path multiplies the whole stack).

    Attributes:
        qr_fallback_epochs, indefinite_marginals: the child's smoother's (after
            :meth:`finish`), as :class:`.batch.SmoothingResult` reports them.
        child_cpu_s: the child's CPU time (user + system), seconds (after :meth:`finish`).
        wait_s: wall time this process spent waiting for the child's poses, seconds.
    """

    def __init__(
        self,
        epochs_planes: Sequence[Sequence[Plane]],
        relative_poses: Sequence[RelativePose],
        config: PlanodomConfig,
        T_world_first: np.ndarray | None = None,
    ) -> None:
        if not hasattr(os, "fork"):
            raise PlanodomError(
                "smoothing.batch_initial_concurrent: true needs os.fork (POSIX); set it false"
            )
        context = multiprocessing.get_context("fork")
        self._conn, child_end = context.Pipe(duplex=False)
        self._process = context.Process(
            target=_run, args=(child_end, epochs_planes, relative_poses, config), daemon=True
        )
        self._process.start()
        child_end.close()
        self._n = len(epochs_planes)
        self._poses: list[np.ndarray] = []
        self._T_world_first = None if T_world_first is None else np.asarray(T_world_first)
        self._done: tuple[list[int], list[tuple[int, float]], float] | None = None
        self.qr_fallback_epochs: list[int] = []
        self.indefinite_marginals: list[tuple[int, float]] = []
        self.child_cpu_s = 0.0
        self.wait_s = 0.0
        self.initial_check: tuple[float, int, int, bool] | None = None  # ("checked" only)

    def __len__(self) -> int:
        return self._n

    def _receive(self) -> None:
        """One message from the child (the next poses, or its end)."""
        start = time.perf_counter()
        try:
            kind, payload = self._conn.recv()
        except EOFError:
            self._process.join()
            raise PlanodomError(
                "the windowed initial guess's process ended without its poses "
                f"(exit code {self._process.exitcode}); set smoothing.batch_initial_concurrent "
                "false"
            ) from None
        finally:
            self.wait_s += time.perf_counter() - start
        if kind == "error":
            self.close()
            raise payload
        if kind == "poses":
            self._poses.extend(payload)
        else:
            self._done = payload

    def __getitem__(self, k: int) -> np.ndarray:
        if not 0 <= k < self._n:
            raise IndexError(f"epoch {k} outside the guess's {self._n} epochs")
        while k >= len(self._poses):
            if self._done is not None:  # cannot happen: the child sends every pose
                raise PlanodomError(f"the windowed initial guess ended without epoch {k}")
            self._receive()
        pose = self._poses[k]
        return pose if self._T_world_first is None else self._T_world_first @ pose

    def finish(self) -> np.ndarray:
        """Wait for the child's end; its (E, 4, 4) poses (without ``T_world_first``)."""
        while self._done is None:
            self._receive()
        self.qr_fallback_epochs, self.indefinite_marginals, self.child_cpu_s = self._done
        self.close()
        return np.stack(self._poses)

    def close(self) -> None:
        """End the child (if still running) and release the pipe; again: nothing."""
        if self._process.is_alive():
            self._process.terminate()
        self._process.join()
        self._conn.close()


@contextmanager
def finished(guess: object) -> Iterator[None]:
    """Around the graph's construction: a :class:`GuessAhead` ``guess`` waited for at the
    end (its QR fallbacks and CPU), its child ended in any case (also where the
    construction failed); anything else untouched."""
    try:
        yield
        if isinstance(guess, GuessAhead):
            guess.finish()
    finally:
        if isinstance(guess, GuessAhead):
            guess.close()
