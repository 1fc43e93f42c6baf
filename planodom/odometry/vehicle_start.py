"""A vehicle's start deskewed with the yaw rate and forward speed of its first degenerate
steps (``odometry.start_vehicle_twist``).

Until a step measures the angular rate, the streaming odometry extracts every epoch
without a twist (a twist never outlives an unresolved epoch). On a rig that starts in a
turn, one sweep an epoch, the undeskewed walls are tilted by the motion over the sweep:
issue 11's world 190 (isoclinal pair, 270 deg, 10 Hz, 3.7 m/s and 15.7 deg/s of yaw at
the start) finds the ground and one wall, 3-6 deg and 30-60 cm off, where the true twist
finds a second wall; the steps on the ground and that wall are degenerate, their yaw rate
right and their roll and pitch 0.4-1.1 deg off, and ``degenerate_gate`` reports each
unresolved (its 14-15 deg/s against the prediction of a start that measured none), so
epochs 1-8 stay unresolved where the oracle measures (docs/RESULTS.md, GAPS5).

Extracted with parts of the true twist (world 190 at 6 mm, epochs 2-7, scratch probe):
the yaw rate alone, or the velocity alone, find fewer planes than no twist; the yaw rate
with the velocity along the base x finds the true twist's planes in every epoch. A
vehicle's roll and pitch rates are small (2 deg/s there) and it has no lateral velocity:
that is the prior here.

So, with the option on, while no step has measured a rate, an epoch whose degenerate step
the gate bridged (:meth:`.twist_sigma.TwistUncertainty.gated`) is extracted again, and its
reference with it, deskewed with the vehicle's twist of that step (:func:`vehicle_twist`),
and estimated again; a degenerate step bridged again gives the next round's twist, up to
``deskew_iterations`` rounds (at least one). The new estimate is kept only when the step
is OK (three normal directions: its rotation checked by its own planes, which a
degenerate step's is not); else the reference's planes come back. From an OK step on,
the run is the usual one (``start_refresh`` deskews the start's epochs with its twist).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planodom.geometry import make_transform, se3_log
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.nonholonomic import lateral_row
from planodom.odometry.relative import Status
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry


def vehicle_twist(estimate: EpochEstimate, dt: float, sin_parallel: float) -> np.ndarray | None:
    """(6,) a vehicle's twist (rad/s, m/s) from a degenerate step ``estimate`` of ``dt`` s:
    its yaw rate (about the base z) and its velocity along the base x, the roll and pitch
    rates and the lateral and vertical velocity zero. The step's translation along the
    direction its associated planes' normals leave unmeasured (the smallest singular
    vector of the reference normals) is the prior's (standing still at a start): it is
    replaced by the one that puts the step on a vehicle's arc (no lateral velocity,
    :func:`.nonholonomic.lateral_row`), as ``odometry.motion_model: nonholonomic`` solves
    it. None when that direction is within ``sin_parallel`` (sine) of the arc's own (a wall
    along the track: the speed is not measured) or no plane was associated."""
    pairs = estimate.relative.associations
    if len(pairs) == 0:
        return None
    normals = np.array([estimate.reference_planes[int(i)].normal for i in pairs[:, 0]])
    u = np.linalg.svd(normals)[2][-1]  # the least measured direction of the translation
    R, t = estimate.step[:3, :3], estimate.step[:3, 3]
    c = lateral_row(R)
    if abs(float(c @ u)) <= sin_parallel:
        return None
    t = t - float(c @ t) / float(c @ u) * u
    own = se3_log(make_transform(R, t)) / dt
    out = np.zeros(6)
    out[2], out[3] = own[2], own[3]
    return out


def vehicle_started(odo: PlaneOdometry, scan: Scan, t: float, best: EpochEstimate) -> EpochEstimate:
    """``best``, the estimate of the epoch ``scan`` at ``t`` s, or the estimate of it and
    its reference deskewed with a vehicle's twist (module docstring) when that is OK."""
    if not odo.config.odometry.start_vehicle_twist or odo._map is not None or odo._rates:
        return best
    ungated = _ungated(odo, best)
    if ungated is None:
        return best
    ref = odo._reference()
    if ref.scan is None:
        return best
    dt = t - odo.times[-1]
    saved, last = (ref.planes, ref.twist, ref.plane_set), odo._last_usable
    sin_parallel = float(np.sin(np.radians(odo.config.association.parallel_angle_deg)))
    for _ in range(max(odo.config.odometry.deskew_iterations, 1)):
        twist = vehicle_twist(ungated, dt, sin_parallel)
        if twist is None:
            break
        odo._set_planes(ref, *odo._extract(ref.scan, twist))
        again = odo._estimate_scan(scan, t, twist)
        if again.relative.status is Status.OK:
            if odo.results[ref.index] is not None:
                odo.superseded.add(ref.index)  # its step refers to planes that are gone
            if ref.has_pair(odo.config.association) and (last is None or last.index <= ref.index):
                odo._last_usable = ref
            return again
        ungated = _ungated(odo, again)
        if ungated is None:
            break
    odo._set_planes(ref, *saved)
    odo._last_usable = last
    return best


def _ungated(odo: PlaneOdometry, estimate: EpochEstimate) -> EpochEstimate | None:
    """The degenerate step ``estimate`` was before ``degenerate_gate`` bridged it (None
    when it was not bridged by the gate)."""
    if not estimate.relative.inconsistent:
        return None
    found = [e for e in odo._twist_sigma.ungated if e.planes is estimate.planes]
    return found[-1] if found else None
