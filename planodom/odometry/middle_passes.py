"""The deskewing passes of a run registered at the sweeps' middles
(``planemap.pass_reference_time: middle``).

:func:`planodom.odometry.run.redeskewed_run` deskews every scan along the curve through
the poses of the pass before, to the middle of its epoch, and registers its last pass at
the epoch times. A lidar's streaming pass with ``planemap.reference_time: middle``
registers each sweep at its middle instead (a twist's error then distorts a scan without
shifting it as a whole) and brings the poses to the epoch times along the curve through
them (:func:`planodom.odometry.planemap.midtime.at_epoch_times`). Here every pass does the
same: the curve's nodes are the previous pass's poses at the sweeps' middles themselves
(not re-interpolated from the epoch times), each scan is deskewed along it to its own
sweep's middle and registered there, and the last pass is brought to the epoch times as
the streaming pass is. All but the first: it is registered at its epoch time, so the
run's first pose (the identity, which turns every later one) is a node of the curve and
not extrapolated half a sweep before the first middle (``planemap.first_pose``: 0.02 deg
on a simulated lidar at sigma = 0, against 1e-4 deg at the later steps; the streaming
pass's middle poses, the first curve's nodes, still have it). It needs the epochs on
both sides of a sweep: offline, or in a stream with a lag of ``deskew_order // 2 + 1``
epochs (the cubic around sweep ``k`` goes through the middles ``k - 1 .. k + 2``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from planodom.config import PlanodomConfig
from planodom.odometry.deskewed_epochs import Curve, DeskewedEpochs
from planodom.odometry.extractor import Extractor
from planodom.odometry.interpolate import curve_steps
from planodom.odometry.planemap.midtime import at_epoch_times
from planodom.odometry.run import (
    EpochSequence,
    OdometryRun,
    _measured,
    _near_all_measured,
    _streaming_pass,
    fit_nodes,
    step_variances,
)
from planodom.odometry.splice import kept_epochs, spliced
from planodom.rig import Rig


def middle_redeskewed_run(
    source: EpochSequence,
    middle_run: OdometryRun,
    streaming: OdometryRun,
    config: PlanodomConfig,
    rig: Rig,
    progress: Callable[[int, int], None] | None = None,
    extractor: Extractor | None = None,
) -> OdometryRun:
    """``odometry.deskew_passes`` passes registered at the sweeps' middles (module
    docstring), the last at the epoch times of ``streaming``.

    Args:
        source: the epochs (scans with point times relative to their epoch times).
        middle_run: the streaming pass registered at the sweeps' middles
            (``middle_run.times`` (N,) s, poses (N, 4, 4)): the first curve's nodes.
        streaming: the same pass at the epoch times (``streaming.times`` (N,) s): with
            ``odometry.deskew_pass_guard: streaming`` an epoch whose last pass did not
            converge keeps its estimate (:func:`planodom.odometry.splice.unconverged`).
        config, rig, progress, extractor: as :func:`planodom.odometry.run.run_odometry`.
    """
    odo = config.odometry
    epoch_times = np.asarray(streaming.times, dtype=np.float64)
    reference = np.asarray(middle_run.times, dtype=np.float64).copy()
    reference[0] = epoch_times[0]  # the first epoch at its epoch time: no pose extrapolated
    order, n_fit = odo.deskew_order, fit_nodes(config, reference)
    run, seconds = middle_run, dict(streaming.seconds)
    measured = _measured(middle_run)
    trusted = _near_all_measured(measured, order)
    curve = Curve(np.asarray(middle_run.times), middle_run.poses, None, order, None)
    for _ in range(odo.deskew_passes):
        steps = step_variances(run, measured)  # node k, the middle of epoch k: its two steps
        variances = 0.5 * (steps + np.r_[steps[1:], steps[-1:]])
        trusted = _near_all_measured(measured, order)
        curve = Curve(np.asarray(run.times), run.poses, variances if n_fit else None, order,
                      n_fit, odo.deskew_fit == "increments")  # fmt: skip
        deskewed = DeskewedEpochs(source, epoch_times, reference, curve, trusted)
        run = _streaming_pass(deskewed, config, rig, reference, progress, extractor)
        measured = _measured(run)
        for key, value in (run.seconds | {"deskew": deskewed.seconds}).items():
            seconds[key] = seconds.get(key, 0.0) + value
    out = at_epoch_times(run, epoch_times, order, config.planemap.first_pose)
    if odo.deskew_pass_guard != "off":
        c = curve
        steps = curve_steps(c.times, c.poses, epoch_times, c.order, c.variances, c.n_fit,
                            c.increments)  # fmt: skip
        out = spliced(streaming, out, kept_epochs(streaming, out, steps, trusted, config))
    out.seconds = seconds
    return out
