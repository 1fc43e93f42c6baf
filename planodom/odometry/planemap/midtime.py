"""Registering each lidar sweep at its middle (``planemap.reference_time: middle``).

The plane-map odometry registers an epoch's planes, deskewed with one constant twist,
against a map. The scan of epoch ``k`` is taken over ``[t_k + t_min, t_k + t_max]``
(a spinning lidar stamped at the start of its sweep: ``[t_k, t_k + 1 / rate]``), while
the twist it is deskewed with comes from the steps before it: it lags the sweep by about
an epoch. A twist error ``e`` moves a plane seen at time ``t`` by about ``e t``, so with
the reference at the sweep's start the whole scan moves by ``e`` times its mean time
and the registration follows (measured on issue 11's lidar worlds, sigma = 0: deskewing
with the true twist of the step before gave 0.026 deg rms per epoch, the one of the sweep
itself 0.0056, the true motion 0.0037; planodom 0.020). With the reference at the
sweep's middle ``t_m = (t_min + t_max) / 2`` the times are centred: the twist error
distorts the scan but no longer shifts it as a whole, and the poses registered there
are the better ones. Measured (``planodom experiment generalisation --worlds 12 --rig
lidar --epochs 100``, worlds 1-11): rotation rms median over the worlds 0.0114 / 0.0119
/ 0.0156 -> 0.0036 / 0.0041 / 0.0071 deg at 0 / 6 / 20 mm, xy rms 0.48 / 0.62 / 1.15
-> 0.23 / 0.33 / 0.75 mm, ATE 5.0 / 5.3 / 4.8 -> 1.4 / 1.8 / 4.4 mm; better on every
world in rotation, but world 7's ATE worse (0.58 -> 1.11 mm at 6 mm, 3.4 -> 9.9 at 20
mm), and about half the epochs/s (the epochs are extracted again more often). At 6 mm
over the lidar worlds 1-19, 300 epochs: rotation 0.0119 -> 0.0046 deg median (22x ->
7.4x the oracle, worst 118x -> 52x), xy 0.46 -> 0.29 mm, ATE 6.4 -> 1.6 mm (24x ->
9x); worse then on world 19 (ATE 8.7 -> 41 mm) and world 7 at 2 cm (4.4 -> 12.1 mm).
Both came from the first epoch's time, before its middle: the cubic extrapolated there
amplified the first steps' errors, and the run's first pose (the identity) turned every
later pose with it (:func:`_pose_at`); on world 19 the first steps were also off by a
vertical drift nobody observed (:mod:`.pose`). With both fixed: better than ``epoch``
on every world in rotation, xy and ATE, 2 % worse on KITTI raw 0005 with its declared
sweep (figures in ``config.planemap.reference_time``), the default since.

The default's figures (``planodom experiment generalisation --worlds 20 --rig lidar
--epochs 300``, the ten lidar worlds, ``epoch`` -> ``middle``): better on every world in
rotation, xy and ATE at 6 mm and 2 cm; medians 6 mm rotation 21.8x -> 6.5x the oracle
(worst 139x -> 51x), xy 2.9x -> 1.7x, ATE 6.5 -> 2.0 mm (28x -> 10x, worst 250x ->
102x); 2 cm rotation 8.5x -> 5.1x, xy 1.9x -> 1.2x, ATE 6.7 -> 2.5 mm (7.6x -> 3.4x);
front end 2.2x -> 1.9x KISS-ICP's epochs/s (more epochs extracted twice). KITTI raw 0005
with its declared sweep (stamped mid-sweep): RPE rotation 0.0743 -> 0.0760 deg,
translation 0.0367 -> 0.0375 m, ATE 1.514 -> 1.515 m (2 % worse); without a sweep (no
point times) unchanged. The default since issue 11: every procedural lidar world better
against a 2 % loss on one drive with a sweep declared by hand (what a run-to-run change
of unrelated settings moves there).

The pairwise pipelines (the 2D rig's, stamped at the start of their sweeps) do the same
with ``odometry.pairwise_reference_time: middle`` (off by default). On the 2D-rig worlds
40-58 the rig rolls by up to a degree per 0.2 s epoch (world 46: rate oscillating with a
1.6 s period); registered at the start, the roll per epoch came out about 10 % short
(0.1 deg) at sigma 0, against 0.01-0.03 deg at the middle (0.12 deg from the snapshot
simulation, no motion within an epoch, with either). Measured (generalisation worlds
0-58 even, the 2D rig, 300 epochs, planodom only, epoch -> middle): 6 mm median rotation
0.072 -> 0.052 deg (better on 23 of 30 worlds), xy 1.62 -> 1.30 cm, ATE 0.148 -> 0.121 m
(15 of 30 better; worse world 8 0.28 -> 2.38 m (its first epoch lost: extracted without
deskewing it kept one plane), 6 1.07 -> 3.38, 22 0.46 -> 1.02, 0 0.25 -> 0.43, 28 0.54
-> 0.80, 14 0.08 -> 0.20), unresolved 75 -> 89; 2 cm rotation 0.199 -> 0.168 deg (23 of
30), ATE 0.78 -> 0.41 m (22 of 30; worse world 6 7.6 -> 19.1 m, 18's rotation 0.23 ->
0.54 deg), unresolved 201 -> 155; world 46 at 6 mm 0.590 -> 0.396 deg, ATE 1.53 -> 0.70
m. Quick start: RPE 2.7 -> 1.6 mm, 0.0175 -> 0.0140 deg, ATE 0.071 -> 0.084 m (xy 0.052
-> 0.051). Off by default: ATE at 6 mm is mixed (geometric mean of the ratios 1.00) and
the quick start's ATE worse.

Each scan's times are shifted by ``-t_m`` before the streaming pass, which then runs at
the times ``t_k + t_m`` (:class:`MiddleTimed`); its poses are brought back to the epoch
times along the curve through them (:func:`planodom.odometry.interpolate.curve_poses`,
``odometry.deskew_order``), as are the relative poses and the planes
(:func:`at_epoch_times`). The curve uses the epochs on both sides, so a pose is final
one epoch later.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from planodom.geometry import Plane, invert_transform
from planodom.odometry.deskew import time_spread
from planodom.odometry.interpolate import curve_poses
from planodom.scan import Scan
from planodom.se3 import se3_exp, se3_log

if TYPE_CHECKING:
    from planodom.odometry.run import EpochSequence, OdometryRun


class MiddleTimed:
    """The epochs of ``source`` with each scan's times centred on its sweep's middle.

    ``offsets[k]`` (s) is the middle ``t_m`` of epoch ``k``'s point times (0 for a scan
    without time spread, or plane lists), known once the epoch was read; ``times`` gives
    the shifted epoch times ``times[k] + offsets[k]`` (read after the epoch, as the
    streaming pass does).
    """

    def __init__(self, source: EpochSequence, times: np.ndarray) -> None:
        self.source = source
        self.epoch_times = np.asarray(times, dtype=np.float64)
        self.offsets = np.zeros(len(self.epoch_times))
        self.times = _ShiftedTimes(self)

    def __len__(self) -> int:
        return len(self.source)

    def __getitem__(self, k: int) -> Scan | Sequence[Plane]:
        item = self.source[k]
        if not isinstance(item, Scan) or not time_spread(item):
            self.offsets[k] = 0.0
            return item
        assert item.t is not None
        middle = 0.5 * (float(np.min(item.t)) + float(np.max(item.t)))
        self.offsets[k] = middle
        return replace(item, t=item.t - middle)


class _ShiftedTimes:
    """``times[k]``: the epoch time of ``k`` plus the offset of its scan (read first)."""

    def __init__(self, owner: MiddleTimed) -> None:
        self.owner = owner

    def __len__(self) -> int:
        return len(self.owner.epoch_times)

    def __getitem__(self, k: int) -> float:
        return float(self.owner.epoch_times[k] + self.owner.offsets[k])


def at_epoch_times(
    run: OdometryRun, epoch_times: np.ndarray, order: int, first: str = "quadratic_fit"
) -> OdometryRun:
    """``run`` (registered at the sweeps' middles, ``run.times``) at the ``epoch_times``
    (N,) s: poses on the curve through its poses (beyond the first or last middle:
    :func:`first_pose` with ``first``, ``planemap.first_pose``), relative poses
    ``D_prev^-1 T_prev_curr D_curr`` and planes moved by ``D_k^-1``, where
    ``D_k = M_k^-1 T_k`` takes epoch ``k``'s base frame at its epoch time to the one at
    its middle (``M_k``: the pose at the middle, ``T_k``: at the epoch time).
    Covariances are kept (``D_k`` turns them by the rotation over half a sweep, a degree
    or so)."""
    middles = np.asarray(run.times, dtype=np.float64)
    epoch_times = np.asarray(epoch_times, dtype=np.float64)
    if len(middles) < 2 or np.allclose(middles, epoch_times, rtol=0.0, atol=1e-12):
        return replace(run, times=epoch_times)
    M = run.poses
    T = np.array([_pose_at(middles, M, t, order, first) for t in epoch_times])
    D = invert_transform(M) @ T  # (N, 4, 4) T_mid_epoch
    D_inv = invert_transform(D)
    T = invert_transform(T[0])[None] @ T  # the first pose stays the identity
    results = []
    for r in run.results:
        if r is not None and r.prev >= 0 and r.curr >= 0:
            r = replace(r, T_prev_curr=D_inv[r.prev] @ r.T_prev_curr @ D[r.curr])
        results.append(r)
    planes = [[p.transformed(D_inv[k]) for p in ps] for k, ps in enumerate(run.planes)]
    return replace(run, poses=T, times=epoch_times, results=results, planes=planes)


def _pose_at(
    middles: np.ndarray, poses: np.ndarray, t: float, order: int, first: str = "quadratic_fit"
) -> np.ndarray:
    """``T_world_base`` (4, 4) at the time ``t`` s on the curve through the ``poses``
    (N, 4, 4) at the ``middles`` (N,) s: the polynomial of ``order`` through the nearest
    nodes between the first and the last middle; beyond them (the first epoch's time
    comes before its middle) :func:`first_pose` with ``first``."""
    if middles[0] <= t <= middles[-1]:
        return curve_poses(middles, poses, t, np.array([t]), order)[0]
    return first_pose(middles, poses, t, first)


def first_pose(
    middles: np.ndarray, poses: np.ndarray, t: float, fit: str = "quadratic_fit"
) -> np.ndarray:
    """``T_world_base`` (4, 4) at the time ``t`` s beyond the first (or last) of the
    ``middles`` (N,) s, extrapolated on the curve through the ``poses`` (N, 4, 4) there
    (``planemap.first_pose``): ``quadratic_fit``, the least-squares quadratic over the
    ``_END_NODES`` nearest; ``quadratic`` / ``cubic``, the polynomial through the nearest
    three / four (fewer nodes: the degree they allow); ``mixed``, roll and pitch from one
    fit, yaw and translation from another (:func:`_mixed`).

    The run's first pose is the identity, so the first pose's error turns the whole run.
    A polynomial extrapolated outside its nodes multiplies their errors: half a node
    spacing before the first node, the cubic through four weights the first three steps'
    errors -1.19, 1.0, -0.31 (gain 1.6), which on issue 11's lidar worlds 7 (2 cm) and
    19 (6 mm) turned ATE 3.4 -> 9.9 mm and 8.7 -> 41 mm; the quadratic through three
    -0.875, 0.375 (gain 0.95); the least-squares quadratic over five the first four
    -0.31, -0.45, -0.05, 0.31 (gain 0.63), and its bias is the motion's third-order term
    over five nodes, where the geodesic through two (gain 0.5) errs by the acceleration
    (0.09 deg for a yaw rate changing by 0.4 rad/s^2: half a sweep in the test's motion).
    Measured (100 epochs): world 7 at 2 cm ATE 9.9 (cubic) / 3.6 (geodesic) / 3.0 mm
    (quadratic fit), world 19 at 6 mm 4.0 / 3.9 / 3.0 mm. On a hand-held walk (10 Hz, a
    swing of 1.45 Hz: seven epochs) five nodes span most of a swing and the fit's bias
    dominates: from the true middle poses it is 5.1 deg off on world 40 (the quadratic
    through three 2.5, the cubic 0.8).

    Measured (the first pose's angle to the truth; ``experiments/handheld_walks.py run W
    NOISE [--vehicle] --set planemap.first_pose=F``, 150 epochs; only the first pose, the
    first step and what the first pose turns change): hand-held worlds 40-47, 6 mm / 2 cm,
    quadratic fit -> quadratic -> cubic, deg: 40 5.52 -> 2.17 -> 0.29 / 5.21 -> 2.22 ->
    0.50; 41 0.32 -> 0.11 -> 0.08 / 0.32 -> 0.10 -> 0.04; 42 0.38 -> 0.18 -> 0.13 / 0.37
    -> 0.16 -> 0.15; 43 2.79 -> 0.68 -> 1.11 / 2.26 -> 0.89 -> 0.24; 44 0.54 -> 1.11 ->
    1.70 / 0.63 -> 0.62 -> 0.98; 45 0.82 -> 0.95 -> 2.24 / 0.52 -> 1.42 -> 2.41; 46 0.13
    -> 0.51 -> 0.77 / 0.14 -> 0.55 -> 0.92; 47 4.3 -> 11.7 -> 11.7 / 2.6 -> 0.5 -> 2.0.
    The middles' own errors (0.1-1 deg a step on the walks, up to 40 times the
    registration's reported sigma) then outweigh the fit's bias as often as not: ATE
    better on 12 of 16 walks with the cubic (geometric mean of the ratios 0.81; world 43
    at 2 cm 0.327 -> 0.130 m), worse on 4 (world 44 at 2 cm 0.123 -> 0.417 m). Vehicle
    lidar worlds 1-19 odd at 6 mm and 2 cm, where the fit's bias is 0.000-0.046 deg from
    the true middles: ATE worse on 15 of 20 with the cubic (geometric mean 1.56; world 7
    at 2 cm 2.8 -> 10.6 mm), on 16 with the quadratic through three (1.35). The fit
    chosen per run by the least estimated error (bias from the difference to the cubic,
    noise from the registration's covariances, or from the nodes' fourth differences)
    took the cubic on the walks where it was worse too; the second was worse on the
    vehicle worlds (ATE geometric mean 1.38): no rule measured here tells the fit's bias
    from the middles' noise with the first five to nine of them."""
    if fit == "mixed":
        return _mixed(middles, poses, t)
    return _polynomial(middles, poses, t, *_FITS[fit])


def _polynomial(
    middles: np.ndarray, poses: np.ndarray, t: float, degree: int, nodes: int
) -> np.ndarray:
    """The pose (4, 4) at ``t`` on the polynomial of ``degree`` through the ``nodes``
    middles nearest ``t``, or (more nodes than the degree needs) their least-squares one
    with equal weights; fewer middles: the degree they allow."""
    n = min(nodes, len(middles))
    degree = min(degree, n - 1)
    if n > degree + 1:
        weights = np.ones((len(middles), 6))
        return curve_poses(middles, poses, t, np.array([t]), degree, weights, n)[0]
    return curve_poses(middles, poses, t, np.array([t]), degree)[0]


def _mixed(middles: np.ndarray, poses: np.ndarray, t: float) -> np.ndarray:
    """``planemap.first_pose: mixed``: in the tangent space of the fits' middle node (their
    chart, :func:`planodom.odometry.interpolate.curve_poses`), roll and pitch (rotation
    x, y) from the least-squares cubic over six middles, yaw (z) and translation from the
    least-squares quadratic over seven. A vehicle's sway in roll and pitch needs the
    cubic; its yaw and translation, which turn and shift the whole run in the plane, are
    smooth, and the longer fit averages their noise (figures: ``config.planemap
    .first_pose``)."""
    n = min(_MIXED[1][1], len(middles))  # the chart both fits use at the first middles
    P = poses[n // 2] if t <= middles[0] else poses[len(middles) - 1 - n // 2]
    P_inv = invert_transform(P)
    xi = se3_log(P_inv @ _polynomial(middles, poses, t, *_MIXED[1]))
    xi[:2] = se3_log(P_inv @ _polynomial(middles, poses, t, *_MIXED[0]))[:2]
    return P @ se3_exp(xi)


_END_NODES = 5
"""Nodes of the least-squares quadratic beyond the first or last middle (:func:`first_pose`)."""

_FITS = {"quadratic_fit": (2, _END_NODES), "quadratic": (2, 3), "cubic": (3, 4)}
"""``planemap.first_pose`` -> (degree, nodes) of its polynomial (:func:`_polynomial`)."""

_MIXED = ((3, 6), (2, 7))
"""``mixed``'s (degree, nodes) for roll and pitch, then for yaw and translation."""
