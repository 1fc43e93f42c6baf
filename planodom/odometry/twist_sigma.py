"""How far off the twist an epoch is deskewed with may be: a per-epoch twist sigma.

The 2D-rig extraction widens its grouping tolerances by the smear a twist error leaves
over the epoch (``extraction.twist_rate_sigma_deg_s`` / ``twist_speed_sigma_mps``,
:func:`planodom.extraction.rig2d.windows.twist_smear`). A fixed sigma large enough for a
predicted twist also widens them for a twist refined from the epoch's own estimate, which
is nearly exact, and lets other points into its planes (the paper loop's quick start:
ATE 0.071 -> 0.175 m with 0.5 deg/s and 0.5 m/s). So the odometry gives each extraction
the sigma of the twist it passes (``odometry.twist_sigma``: ``lost``, the default, widens
only an epoch the tight extraction loses, :func:`widened_if_lost`), from this model:

- a step measured over ``dt`` gives its twist with the error of the step itself: the
  square roots of the traces of the rotation and translation blocks of its covariance
  (and ``sigma_z`` when the vertical was measured), over ``dt``;
- the twist of the epoch's points (acquired after its reference time) differs from the
  twist of the step before it by the change of the twist over one epoch: the rms of the
  differences of successive measured twists (measurement noise included, so it errs on
  the large side), ``change``;
- a refined twist (:meth:`TwistUncertainty.refined`): the step's error, one ``change``,
  and what the deskewing policy left of the difference (a component is only replaced when
  it differs by more than ``deskew_*_tolerance``, so the twist used may keep that much);
  the velocity of a twist refined from a degenerate step is the prediction's (not
  measured, kept), and so is its sigma;
- a predicted twist (the last step's, :meth:`TwistUncertainty.predicted`): the last
  step's error and two ``change`` (one step older), plus one ``change`` per unresolved
  epoch since (a twist held over them);
- until two successive twists were measured, ``change`` is unknown: the deskewing
  tolerances stand in for it (the error the deskewing policy leaves anyway).
"""

from __future__ import annotations

import functools
from collections import deque
from collections.abc import Callable
from dataclasses import replace
from typing import Literal, cast

import numpy as np
from scipy.stats import chi2

from planodom.config import ExtractionConfig, OdometryConfig
from planodom.geometry import se3_exp, vector_norm
from planodom.odometry.change_gate import step_sigma
from planodom.odometry.deskew import EpochEstimate, keep_first, prefer_streaming
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.twist_blend import RateBlend

#: (angular rate sigma rad/s, linear velocity sigma m/s)
TwistSigma = tuple[float, float]


@functools.cache
def chi2_quantile(q: float, dof: int) -> float:
    """``chi2.ppf(q, dof)``, remembered: the gate's quantile and DoF come from the config,
    and scipy.stats costs ~0.2 ms a call (a few calls an epoch when the gate runs)."""
    return float(chi2.ppf(q, dof))


class TwistUncertainty:
    """The running state of the model (module docstring) in the streaming odometry."""

    def __init__(self, config: OdometryConfig):
        self._fallback = np.array(
            [np.radians(config.deskew_rate_tolerance_deg_s), config.deskew_speed_tolerance_mps]
        )
        self._tolerance = self._fallback.copy()
        # differences of successive measured twists (the change is a property of the
        # motion: it is kept across unresolved epochs, only not measured over them)
        self._changes: deque[np.ndarray] = deque(maxlen=config.velocity_window)
        self._raw_changes: deque[np.ndarray] = deque(maxlen=config.velocity_window)  # noise in
        self._previous: np.ndarray | None = None  # the last measured twist, when the last
        self._previous_var = np.zeros(2)  # and its step's variance
        self._last = self._fallback.copy()  # the last measured step's sigma
        self._unresolved = 0  # unresolved epochs since the last measured one
        # the angular rate's change measured across degenerate steps too (for the gates)
        self._rate_changes: deque[float] = deque(maxlen=config.velocity_window)
        # what change() and predicted() return until the next update (asked for with
        # every extraction of an epoch)
        self._memo: dict[object, object] = {}
        # the estimates gated()'s gate bridged since the last update (their steps before it)
        self.ungated: list[EpochEstimate] = []
        # degenerate_gate_release: the own twists of this epoch's gated steps (by the id of
        # the relative pose the gate made), and the committed one's since the last kept step
        self._gated_twists: dict[int, tuple[RelativePose, np.ndarray]] = {}
        self._gated_rate: np.ndarray | None = None
        self.blend = RateBlend(config, self.change)  # odometry.twist_blend

    def update(
        self, own: np.ndarray, relative: RelativePose, dt: float, plane_map: object = None
    ) -> np.ndarray:
        """Record a committed epoch's own twist ``own`` (6,) and its step's ``relative``;
        returns ``own`` with its rate blended with the prediction (``odometry.twist_blend``,
        :mod:`.twist_blend`; ``own`` itself when off or under a plane map ``plane_map``)."""
        self._memo.clear()
        self.ungated.clear()
        if relative.status is not Status.UNRESOLVED:
            self._gated_rate = None  # a kept step: the gate's prediction is its
        elif relative.inconsistent:
            kept = self._gated_twists.get(id(relative))  # held: ids are not reused
            self._gated_rate = None if kept is None else kept[1]
        self._gated_twists.clear()
        blended = own if plane_map is not None else self.blend.committed(own, relative, dt)
        if relative.status is Status.UNRESOLVED:
            self._unresolved += 1
            self._previous = None
            return blended
        self._unresolved = 0
        sigma = step_sigma(relative, dt)
        self._last = np.where(np.isfinite(sigma), sigma, self._fallback)
        # a degenerate step measures the angular rate, not the velocity (NaN: not measured
        # across it); the rate's change is, for the gates (:meth:`gate_change`)
        own = np.array(own, dtype=float)
        if relative.status is not Status.OK:
            own[3:] = np.nan
        var = self._last**2
        if self._previous is not None:
            # the difference of two measured twists holds both their errors: what is left
            # of its square is the change of the motion
            d = own - self._previous
            sq = np.maximum(np.array([d[:3] @ d[:3], d[3:] @ d[3:]]) - var - self._previous_var, 0)
            self._rate_changes.append(float(sq[0]))
            if np.isfinite(sq[1]):  # two OK steps
                self._changes.append(sq)
                self._raw_changes.append(np.array([d[:3] @ d[:3], d[3:] @ d[3:]]))
        self._previous, self._previous_var = own, var
        return blended

    def change(self) -> np.ndarray:
        """(2,) rms change of the angular rate (rad/s) and velocity (m/s) over one epoch,
        between OK steps."""
        if "change" not in self._memo:
            changes = self._changes
            mean = np.sqrt(np.mean(np.array(changes), axis=0)) if changes else self._fallback
            self._memo["change"] = mean
        return cast("np.ndarray", self._memo["change"])

    def raw_change(self) -> np.ndarray:
        """(2,) rms of the differences of successive measured twists between OK steps,
        their errors left in (rad/s, m/s): the change of the motion over one epoch with
        the measurement noise, no step's stated covariance subtracted; the deskewing
        tolerances before two were measured (as :meth:`change`)."""
        if not self._raw_changes:
            return self._fallback.copy()
        return np.sqrt(np.mean(np.array(self._raw_changes), axis=0))

    def gate_change(self) -> np.ndarray:
        """:meth:`change` with the angular rate's measured across degenerate steps too: on
        a rig whose roll and pitch rates shake from epoch to epoch they change as much
        between degenerate steps (issue 11's world 0 at 2 cm, where few OK steps follow
        each other: 3-6 deg/s of roll rate an epoch; from OK steps alone, the degenerate
        gate bridged 15 right degenerate steps there). Not given to the extraction: a
        wider sigma there widens rescues too, measured worse on issue 11's worlds."""
        change = self.change()
        if self._rate_changes:
            change = np.r_[np.sqrt(np.mean(self._rate_changes)), change[1]]
        return change

    def predicted(self, gate: bool = False) -> TwistSigma:
        """Sigma of the twist predicted (or held) for the next epoch (``gate``: with
        :meth:`gate_change`)."""
        if gate not in self._memo:
            change = self.gate_change() if gate else self.change()
            s = self._last + (2 + self._unresolved) * change
            self._memo[gate] = (float(s[0]), float(s[1]))
        return cast("TwistSigma", self._memo[gate])

    def bridged_rotation_sigma(self, dt: float) -> float:
        """Sigma (rad, a root of a trace over 3 axes) of the rotation a bridge holds over
        the ``n`` steps of ``dt`` s since the last measured one (this one included): the
        predicted rate's sigma of each, ``last + (1 + j) change`` for the j-th, summed
        (a held rate's error is common to the steps; ``odometry.bridge_normals:
        weighed``)."""
        n = self._unresolved + 1
        return float(dt * (n * self._last[0] + self.change()[0] * (n + n * (n + 1) / 2)))

    def refined(self, source: EpochEstimate, dt: float, twist: np.ndarray) -> TwistSigma:
        """Sigma of ``twist`` (6,) refined from ``source``'s own twist over ``dt`` s."""
        own = source.own_twist(dt)
        sigma = step_sigma(source.relative, dt)
        sigma = np.where(np.isfinite(sigma), sigma, self._tolerance)
        left = np.array([vector_norm(twist[:3] - own[:3]), vector_norm(twist[3:] - own[3:])])
        s = sigma + self.change() + left
        if source.relative.status is not Status.OK:
            # its velocity is the prediction's, kept (not measured): so is its sigma
            s[1] = self.predicted()[1]
        return float(s[0]), float(s[1])

    def consistent(
        self,
        candidate: EpochEstimate,
        dt: float,
        prediction: np.ndarray | None,
        config: OdometryConfig,
        gate: Literal["degenerate", "rate", "twist", "off"] | None = None,
    ) -> bool:
        """Whether ``candidate``'s own twist over ``dt`` s agrees with the constant-velocity
        ``prediction`` (6,), as ``config.rescue_gate`` says: the difference of each part
        gated (the angular rate, with ``degenerate`` only of a degenerate step; with
        ``twist`` the velocity too when the step is OK) holds
        the predicted twist's error and the step's own, each sigma the root of a trace
        over 3 axes, so ``3 |d|^2 / (s_pred^2 + s_step^2)`` summed is chi2 with 3 DoF a
        part, gated at ``config.rescue_gate_quantile``. True when there is nothing to
        compare or not gated (off, no prediction, unresolved: a bridge). ``gate`` stands
        for ``config.rescue_gate`` when given."""
        status = candidate.relative.status
        gate = config.rescue_gate if gate is None else gate
        if gate == "off" or prediction is None or dt <= 0:
            return True
        if status is Status.UNRESOLVED or (gate == "degenerate" and status is Status.OK):
            return True
        d = candidate.own_twist(dt) - prediction
        gated = config.degenerate_gate != "off"  # its change model for the rescue gate too
        var = np.array(self.predicted(gated)) ** 2 + step_sigma(candidate.relative, dt) ** 2
        stat, dof = 3 * (d[:3] @ d[:3]) / var[0], 3
        if gate == "twist" and status is Status.OK:
            stat, dof = stat + 3 * (d[3:] @ d[3:]) / var[1], 6
        return bool(stat <= chi2_quantile(config.rescue_gate_quantile, dof))

    def gated(
        self,
        estimate: EpochEstimate,
        dt: float,
        prediction: np.ndarray | None,
        T_ref_last: np.ndarray,
        config: OdometryConfig,
        bridging: np.ndarray | None = None,
    ) -> EpochEstimate:
        """``estimate`` as ``config.degenerate_gate`` says: a degenerate step whose angular
        rate disagrees with the constant-velocity ``prediction`` (6,) (:meth:`consistent`,
        ``degenerate``) is reported unresolved and ``inconsistent`` and bridged as the
        odometry bridges an unresolved one (``T_ref_last`` (4, 4): ``T_{ref}_{k-1}``),
        with ``bridging`` (6,) (``odometry.bridge_rate``; None: ``prediction``). With
        ``odometry.gap_end_rate: span`` a measured step whose reference is further back
        than the epoch before gets its own twist over the span first (``span_epochs``)."""
        span = estimate.relative.delta if config.delta == 1 else 1  # delta > 1: every step
        if config.gap_end_rate == "span" and span > 1 and estimate.relative.measured:
            estimate = replace(estimate, span_epochs=span)
        if config.degenerate_gate == "off" or estimate.relative.status is not Status.DEGENERATE:
            return estimate
        if prediction is None or self.consistent(estimate, dt, prediction, config, "degenerate"):
            return estimate
        held = self._gated_rate  # degenerate_gate_release: the last gated step's own twist
        if config.degenerate_gate_release == "agreeing" and held is not None:
            if self.consistent(estimate, dt, held, config, "degenerate"):
                return estimate  # two successive measurements overrule the prediction
        self.ungated.append(estimate)  # the step before the gate (start_vehicle_twist)
        step = se3_exp((prediction if bridging is None else bridging) * dt)
        no_pairs = np.zeros((0, 2), dtype=np.intp)
        relative = replace(
            estimate.relative, T_prev_curr=T_ref_last @ step, status=Status.UNRESOLVED,
            associations=no_pairs, sources=None, inconsistent=True,
        )  # fmt: skip
        if config.degenerate_gate_release == "agreeing":
            self._gated_twists[id(relative)] = (relative, estimate.own_twist(dt))
        return replace(estimate, relative=relative, step=step)


def widened_if_lost(
    estimate: Callable[[TwistSigma | None], EpochEstimate],
    sigma: TwistSigma | None,
    mode: Literal["lost", "always", "fixed"],
    previous_planes: int,
    consistent: Callable[[EpochEstimate], bool] = lambda _: True,
    surfaces: Callable[[EpochEstimate], int] | None = None,
) -> EpochEstimate:
    """One extraction of an epoch with a twist of ``sigma`` (None: exact or no twist), as
    ``odometry.twist_sigma`` says: ``lost``: first with the extraction's own tolerances,
    and again widened by ``sigma`` only when that leaves the epoch unresolved or with far
    fewer planes than the one before (:func:`.deskew.prefer_streaming`), the better of
    the two kept, the widened one only when ``consistent`` with the prediction
    (:meth:`TwistUncertainty.consistent`); ``always``: widened; ``fixed``: the
    extraction's tolerances.
    ``estimate(sigma)`` extracts with that sigma (None: the extraction config's) and
    estimates the relative pose. ``surfaces`` (``odometry.twist_sigma_fragments``): an
    estimate's distinct surfaces; with it, a first extraction with fewer than its planes
    (a wall split per sweep) is lost too, and is kept over the widened one only with a
    better status or, at the same status, as many distinct surfaces."""
    if sigma is None or mode == "fixed":
        return estimate(None)
    if mode == "always":
        return estimate(sigma)
    tight = estimate(None)
    split = surfaces is not None and surfaces(tight) < len(tight.planes)
    if not split and not prefer_streaming(tight, previous_planes):
        return tight
    wide = estimate(sigma)
    if split:
        assert surfaces is not None
        rank = lambda e: (e.relative.status.rank, surfaces(e))  # noqa: E731
        first = rank(tight) >= rank(wide)
    else:
        first = keep_first(tight, wide)
    return tight if first or not consistent(wide) else wide


def widened(
    config: ExtractionConfig, twist: np.ndarray | None, sigma: TwistSigma | None
) -> ExtractionConfig:
    """``config`` with its twist sigmas raised to ``sigma`` (rad/s, m/s) for an extraction
    deskewed with ``twist`` (unchanged without either): the 2D-rig path widens its
    tolerances by the smear they leave."""
    if sigma is None or twist is None:
        return config
    rate = max(config.twist_rate_sigma_deg_s, float(np.degrees(sigma[0])))
    speed = max(config.twist_speed_sigma_mps, sigma[1])
    update = {"twist_rate_sigma_deg_s": rate, "twist_speed_sigma_mps": speed}
    return config.model_copy(update=update)
