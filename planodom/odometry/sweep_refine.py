"""Passes of the odometry on scans deskewed by the motion measured inside every epoch
(``sweep_refine.passes``; the measurement: :mod:`planodom.odometry.sweep_motion`).

Each pass measures the motion inside every epoch whose pose and whose reference epoch's
(the one before; for the first epoch, the one after) were measured (not unresolved)
against the reference epoch's planes, along the run's poses; deskews those epochs by it,
point by point; and runs the streaming odometry again on them (the others are deskewed
as the streaming odometry does). The next pass measures again against the new planes.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Sequence

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, invert_transform
from planodom.odometry.deskewed_epochs import Deskewed
from planodom.odometry.extractor import Extractor
from planodom.odometry.run import EpochSequence, OdometryRun, _measured, _streaming_pass
from planodom.odometry.splice import spliced, unconverged
from planodom.odometry.sweep_motion import SweepMotion, epoch_motion
from planodom.odometry.sweep_prior import twist_change
from planodom.rig import Rig
from planodom.scan import Scan


def sweep_refined_run(
    source: EpochSequence,
    run: OdometryRun,
    config: PlanodomConfig,
    rig: Rig,
    progress: Callable[[int, int], None] | None = None,
    extractor: Extractor | None = None,
) -> OdometryRun:
    """``config.sweep_refine.passes`` passes (see the module) after ``run``, the odometry
    of ``source`` with ``config`` (the rig's motion bounds applied); the last pass's run,
    its ``seconds`` adding up all passes' (the measurement as ``sweep_refine``). With
    ``sweep_refine.guard: streaming`` an epoch where the last pass did not converge keeps
    the streaming estimate (:func:`planodom.odometry.splice.unconverged`, the step
    compared with the one of the poses its motion was measured along; an epoch without a
    measured motion keeps it too)."""
    seconds = dict(run.seconds)
    streaming, along, motions = run, run.poses, {}
    for _ in range(config.sweep_refine.passes):
        c0 = _time.perf_counter()
        motions = epoch_motions(source, run, config)
        spent = _time.perf_counter() - c0
        along = run.poses
        run = _streaming_pass(_SweepDeskewed(source, motions), config, rig, run.times,
                              progress, extractor)  # fmt: skip
        for key, value in (run.seconds | {"sweep_refine": spent}).items():
            seconds[key] = seconds.get(key, 0.0) + value
    if config.sweep_refine.guard == "streaming" and config.sweep_refine.passes:
        steps = invert_transform(along[:-1]) @ along[1:]
        measured = np.array([k in motions for k in range(len(run.poses))], dtype=bool)
        run = spliced(streaming, run, unconverged(streaming, run, steps, measured, config))
    run.seconds = seconds
    return run


def epoch_motions(
    source: EpochSequence, run: OdometryRun, config: PlanodomConfig
) -> dict[int, SweepMotion]:
    """The motion inside every epoch of ``source`` it can be measured in (see the module),
    by epoch index."""
    measured = _measured(run)
    n = len(source)
    noise = config.extraction.range_noise_m
    change = twist_change(run.times, run.poses, run.results)
    out: dict[int, SweepMotion] = {}
    for k in range(n):
        r = k - 1 if k > 0 else 1
        if r >= n or not (measured[k] and measured[r]) or r >= len(run.planes):
            continue
        item = source[k]
        if not isinstance(item, Scan) or item.t is None:
            continue
        motion = epoch_motion(item, k, r, run.times, run.poses, list(run.planes[r]),
                              config.sweep_refine, noise, change)  # fmt: skip
        if motion is not None:
            out[k] = motion
    return out


class _SweepDeskewed:
    """``source``'s epochs, those with a measured motion given with their points deskewed
    by it (:class:`planodom.odometry.deskewed_epochs.Deskewed`), the others as they are."""

    def __init__(self, source: EpochSequence, motions: dict[int, SweepMotion]) -> None:
        self.source, self.motions = source, motions

    def __len__(self) -> int:
        return len(self.source)

    def __getitem__(self, k: int) -> Scan | Sequence[Plane] | Deskewed:
        item = self.source[k]
        if not isinstance(item, Scan) or k not in self.motions:
            return item
        out = self.motions[k].deskewed(item)
        return Deskewed(item, Scan(out.points, out.ring, item.t, out.label))
