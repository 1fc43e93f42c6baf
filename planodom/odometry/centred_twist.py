"""The epoch's own angular rate led to its points' mean time (``odometry.deskew_rate_lead``).

A 2D-rig epoch holds the points of the ``T`` seconds after its reference time ``t_k`` (their
mean time ``t_k + tm``). Step 2 of :mod:`planodom.odometry.deskew` extracts it again with
its own twist, the mean over its step ``[t_{k-1}, t_k]``: centred ``dt / 2 + tm`` before
its points (0.19 s on a 5 Hz rig whose sweeps take 0.18 s). Where the turn rate changes,
that lag splits walls into one plane per sweep: on the 2D-rig world 166 (a left turn
leaving its 23 deg/s peak, about 1.3 deg/s less an epoch) the true twist of the step into
epochs 74-78 is 1.1-1.35 deg/s high in yaw, and extracted with it (sigma 0 and 6 mm) they
keep 2-5 of their 4-6 true surfaces in 3-8 planes; with its yaw rate led to the points'
mean time along its change since the step before, they keep all of them, once each, with
the ground (docs/RESULTS.md, TURNLAG).

:func:`centring` gives the lead: each refinement's own rate ``w_k`` becomes ``w_k + (w_k -
w_{k-1}) (dt / 2 + tm) / dt``, ``w_{k-1}`` the previous epoch's own rate (a straight line
through the two step means, ``dt`` apart, evaluated ``dt / 2 + tm`` after the later one),
for the yaw rate (``yaw``: about the base frame's z; the roll and pitch rates of a vehicle
sway faster than an epoch, and one step measures them far less well: on world 166 at 6
mm, epochs 68-81, the own rates were 0.3-6.0 deg/s off the true step's in roll and pitch,
0.03-1.6 in yaw but at one degenerate step, 7.0) or for the whole rate (``rate``);
``yaw_split``: the yaw rate of an extraction that
splits a wall (fewer distinct surfaces than planes) only: a deskewing error common to
successive epochs cancels in their step, a lead that differs from epoch to epoch does not.
The change is shrunk by how well the two steps' covariances tell it apart from their noise
(a steady turn or a straight road is not led), and only the rates of OK steps (rotation and
translation measured) are led and lead: there the degenerate steps' own rates were up to 7.0
deg/s off the true step's in yaw and 6.0 in roll and pitch, and a lead doubles such errors.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.surfaces import distinct_surfaces

if TYPE_CHECKING:
    from planodom.odometry.deskew import EpochEstimate


@dataclass(frozen=True)
class Centring:
    """The lead of one epoch's own rate (module docstring).

    Attributes:
        previous: (3,) the previous epoch's own angular rate, rad/s.
        previous_var: (3,) its variances, (rad/s)^2 (inf: unknown, nothing is led).
        dt: the step's seconds; steps: how far the own rate is led, in steps: ``(dt / 2
            + tm) / dt``.
        axes: (3,) bool, the rate's components led.
        split: with ``yaw_split``, whether an extraction's planes split a wall (fewer
            distinct surfaces than planes, :func:`.surfaces.distinct_surfaces`); None:
            every OK step's rate is led.
    """

    previous: np.ndarray
    previous_var: np.ndarray
    dt: float
    steps: float
    axes: np.ndarray
    split: Callable[[list[Plane]], bool] | None = None

    def led_for(self, own: np.ndarray, estimate: EpochEstimate) -> np.ndarray:
        """(6,) :meth:`led` for the own twist ``own`` of ``estimate``; with ``split``, only
        when ``split(estimate.planes)`` (else ``own`` as it is)."""
        if self.split is not None and not self.split(estimate.planes):
            return np.array(own, dtype=np.float64, copy=True)
        return self.led(own, estimate.relative)

    def led(self, own: np.ndarray, relative: RelativePose | None = None) -> np.ndarray:
        """(6,) ``own`` (rad/s, m/s; the twist of the step ``relative``) with its rate's
        ``axes`` led by ``steps`` along its change since ``previous``, shrunk where the
        change is not told apart from the two rates' noise: ``change (1 - var / change^2)``,
        at least 0, ``var`` the sum of their variances (the rotation block of the step's
        covariance over ``dt^2``; :func:`planodom.odometry.trend.trend_twist` shrinks its
        slope so). The velocity as it is; ``own`` as it is when the step is not OK.
        ``relative`` None: an OK step of no variance."""
        out = np.array(own, dtype=np.float64, copy=True)
        if relative is not None and relative.status is not Status.OK:
            return out
        change = out[:3] - self.previous
        var = self.previous_var + _rate_variances(relative, self.dt)
        shrink = np.clip(1.0 - var / np.maximum(change**2, 1e-300), 0.0, 1.0)
        out[:3] += np.where(self.axes, change * shrink * self.steps, 0.0)
        return out


def _rate_variances(relative: RelativePose | None, dt: float) -> np.ndarray:
    """(3,) the variances of a step's angular rate, (rad/s)^2: its covariance's rotation
    diagonal over ``dt^2`` (zeros without a step, inf without a covariance)."""
    if relative is None:
        return np.zeros(3)
    cov = relative.covariance
    if cov is None or not np.all(np.isfinite(np.diag(cov)[:3])):
        return np.full(3, np.inf)
    return np.diag(cov)[:3] / dt**2


def centring(
    rates: Sequence[tuple[int, np.ndarray]],
    k: int,
    times: np.ndarray | None,
    dt: float,
    config: PlanodomConfig,
    last: RelativePose | None = None,
) -> Centring | None:
    """The lead of epoch ``k``'s own rate under ``config.deskew_rate_lead`` (None: off,
    no points' times, or the previous epoch's rate not measured).

    Args:
        rates: (epoch, own twist (6,) rad/s, m/s) of the recent epochs that measured
            their rate (the pairwise odometry's ``_rates``).
        k: the epoch; times: its points' times (N,), seconds after its reference time.
        dt: seconds since the previous epoch (its step and the one before taken as equal).
        last: the previous epoch's relative pose: its rate is used only when its status is
            OK (a degenerate step's rate can be degrees a second off), with its covariance
            (None: not checked, of no variance).
    """
    mode = config.odometry.deskew_rate_lead
    if mode == "off" or times is None or not len(times) or dt <= 0:
        return None
    if not rates or rates[-1][0] != k - 1:
        return None
    if last is not None and last.status is not Status.OK:
        return None
    steps = 0.5 + float(np.mean(times)) / dt
    axes = np.array([False, False, mode != "rate"]) if mode != "rate" else np.ones(3, bool)
    previous = np.array(rates[-1][1][:3], dtype=np.float64)
    split = None
    if mode == "yaw_split":
        tol_deg, tol_m = config.association.normal_tol_deg, config.association.offset_tol_m
        split = lambda planes: distinct_surfaces(planes, tol_deg, tol_m) < len(planes)  # noqa: E731
    return Centring(previous, _rate_variances(last, dt), dt, steps, axes, split)
