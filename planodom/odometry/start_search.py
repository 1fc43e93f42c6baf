"""A vehicle's twist searched for an unresolved step at the start
(``odometry.start_twist_search``).

Until a step measures the angular rate, the streaming odometry extracts every epoch
without a twist. A vehicle that starts in a turn smears its 2D rig's walls over the
epoch's sweep: issue 11's world 292 at 6 mm (36 deg/s of yaw at 4.5 m/s at its start,
0.175 s sweeps) leaves steps 1-3 unresolved, each 5-2 deg off in yaw, a heading the
whole lap keeps (ATE 8.0 m; docs/RESULTS.md, GAP292), where the same epochs deskewed
with the true twist give OK steps. ``start_vehicle_twist`` takes its twist from a
degenerate step; an unresolved step has none to give. Deskewed with the yaw rate alone
(the true one) step 1 stays unresolved there: the velocity smears the walls as much.

So, with the option on, while no step has measured a rate (pairwise pipelines, the first
:data:`MAX_SEARCHED` epochs), an epoch whose step is unresolved is extracted again, with
its reference, deskewed with each of a vehicle's twists (:func:`candidates`: a yaw rate
about the base z and a speed along the base x, no other rate or velocity), and estimated
again with that twist's constant-velocity prediction as its prior (what the odometry
does with a twist it knows; ``degenerate_gate`` judges the step's rate against it). Of
the candidates whose step is measured (OK first, then degenerate), the one whose step's
own yaw rate is nearest the rate it was deskewed with (the deskewing agrees with the
motion it measures) is refined: both epochs extracted again with the vehicle's twist
of its step (:func:`refined_twist`), up to ``deskew_iterations`` rounds, each kept while
the step's status is no worse. Without a measured candidate the reference's planes come
back and the estimate is the one before. Once a step is OK the run is the usual one
(``start_refresh`` deskews the start's epochs with its twist).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planodom.geometry import se3_log
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.relative import Status
from planodom.odometry.vehicle_start import vehicle_twist
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry

#: The largest yaw rate tried, deg/s: a car's turn at walking pace to a roundabout
#: (about 60 deg/s at 3 m/s on a 3 m radius), not taken from any world.
MAX_RATE_DEG_S = 60.0

#: The yaw rates' spacing, deg/s: the rates are +-k * RATE_STEP_DEG_S, k = 1 .. N.
RATE_STEP_DEG_S = 10.0

#: The forward speeds tried, m/s: a car's in a turn (walking pace to 22 km/h), 1.5 m/s
#: apart; not taken from any world.
SPEEDS_MPS = (1.5, 3.0, 4.5, 6.0)

#: The statuses a candidate's step is kept with (measured: OK, then degenerate).
MEASURED = (Status.OK, Status.DEGENERATE)

#: Epochs at the start searched at most (as many as the start's refresh holds,
#: :data:`.start_epochs.MAX_EPOCHS`): a bound on the extractions spent.
MAX_SEARCHED = 20


def candidates() -> list[np.ndarray]:
    """The vehicle's twists tried (6,): each yaw rate (both signs, nearest zero first)
    with each speed."""
    n = int(round(MAX_RATE_DEG_S / RATE_STEP_DEG_S))
    rates = [s * k * RATE_STEP_DEG_S for k in range(1, n + 1) for s in (1.0, -1.0)]
    return [np.array([0.0, 0.0, np.radians(r), v, 0.0, 0.0]) for r in rates for v in SPEEDS_MPS]


def vehicle_part(estimate: EpochEstimate, dt: float) -> np.ndarray:
    """(6,) the yaw rate and the velocity along the base x of the step's own twist over
    ``dt`` s (rad/s, m/s), the other components zero (a vehicle's)."""
    own = se3_log(estimate.step) / dt
    out = np.zeros(6)
    out[2], out[3] = own[2], own[3]
    return out


def refined_twist(estimate: EpochEstimate, dt: float, sin_parallel: float) -> np.ndarray:
    """(6,) the next round's twist from a measured step: an OK step's :func:`vehicle_part`;
    a degenerate one's with its speed solved on the vehicle's arc
    (:func:`.vehicle_start.vehicle_twist`: its unmeasured direction is the prior's),
    where the arc fixes it."""
    if estimate.relative.status is Status.DEGENERATE:
        twist = vehicle_twist(estimate, dt, sin_parallel)
        if twist is not None:
            return twist
    return vehicle_part(estimate, dt)


def searched_start(odo: PlaneOdometry, scan: Scan, t: float, best: EpochEstimate) -> EpochEstimate:
    """``best``, the estimate of the epoch ``scan`` at ``t`` s, or, when it is an
    unresolved step of the start, the estimate of it and its reference deskewed with a
    searched vehicle's twist (module docstring)."""
    ocfg = odo.config.odometry
    if not ocfg.start_twist_search or odo._map is not None or odo._rates:
        return best
    if best.relative.status is not Status.UNRESOLVED or len(odo.poses) > MAX_SEARCHED:
        return best
    ref = odo._reference()
    dt = t - odo.times[-1]
    if ref.scan is None or dt <= 0:
        return best
    saved, last, predicted = (ref.planes, ref.twist, ref.plane_set), odo._last_usable, odo.twist

    def tried(twist: np.ndarray) -> tuple[EpochEstimate, tuple]:
        odo._set_planes(ref, *odo._extract(ref.scan, twist))  # type: ignore[arg-type]
        odo.twist = twist  # the prior and the gate's prediction
        try:
            again = odo._estimate_scan(scan, t, twist)
        finally:
            odo.twist = predicted
        return again, (ref.planes, ref.twist, ref.plane_set)

    # (-status rank, |own yaw rate - used|, order, twist, estimate, the reference's planes)
    found: list[tuple] = []
    for twist in candidates():
        again, planes = tried(twist)
        if again.relative.status in MEASURED:
            gap = abs(vehicle_part(again, dt)[2] - twist[2])
            found.append((-again.relative.status.rank, gap, len(found), twist, again, planes))
    if not found:
        odo._set_planes(ref, *saved)
        odo._last_usable = last
        return best
    *_, used, kept, planes = min(found, key=lambda f: f[:3])
    sin_parallel = float(np.sin(np.radians(odo.config.association.parallel_angle_deg)))
    for _ in range(ocfg.deskew_iterations):
        new = refined_twist(kept, dt, sin_parallel)
        if np.array_equal(new, used):
            break
        again, new_planes = tried(new)
        if again.relative.status.rank < kept.relative.status.rank:
            break
        kept, used, planes = again, new, new_planes
    odo._set_planes(ref, *planes)
    if odo.results[ref.index] is not None:
        odo.superseded.add(ref.index)  # its step refers to planes that are gone
    if ref.has_pair(odo.config.association) and (last is None or last.index <= ref.index):
        odo._last_usable = ref
    return kept
