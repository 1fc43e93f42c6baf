"""The relative pose between two epochs: what the odometry measures and the smoother uses.

One type, :class:`RelativePose`, flows from the solver (:func:`planodom.odometry.
estimate_relative_pose`) through the streaming odometry into the factor graph
(:mod:`planodom.smoothing`): the transform, its 5-DoF covariance, a :class:`Status`, the
strict plane associations that track planes into landmarks, and the winning plane pairs it
was computed from. How the solver found it (candidates, consensus scores) is kept apart in
:class:`SolverDiagnostics`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, TypeVar

import numpy as np

from planodom.association import PairAssociations
from planodom.consensus import ConsensusResult
from planodom.geometry import rpy_from_rotation


class Status(StrEnum):
    """What a relative pose measured, from worst to best (the order is the ranking).

    - ``UNRESOLVED``: nothing (no associated non-parallel pair); ``T_prev_curr`` is the
      prior, identity without one. The streaming odometry bridges it by constant velocity.
    - ``DEGENERATE``: the rotation, not the horizontal translation (no pair has a
      vertical-enough intersection, or the translation found exceeds the motion bound;
      the translation is the prior's or zero).
    - ``OK``: rotation and horizontal translation.
    """

    UNRESOLVED = "unresolved"
    DEGENERATE = "degenerate"
    OK = "ok"

    @property
    def rank(self) -> int:
        """0 (unresolved) < 1 (degenerate) < 2 (ok)."""
        return _RANK[self]


_RANK = {status: rank for rank, status in enumerate(Status)}


@dataclass(frozen=True, eq=False)
class SolverDiagnostics:
    """How the solver found a relative pose (for CSV rows, tests and experiments).

    Attributes:
        pipeline: the pipeline name (``odometry.pipeline``).
        lda: the LDA pair associations (indices into the input plane lists).
        rotation_consensus, translation_consensus: consensus results (None when not run).
        n_translation_pairs: pairs that gave a reference point in both epochs.
        used_prior: the LDA bounds were applied around the prior.
        rotation_pair, translation_pair: (4,) ``(i1, i2, j1, j2)`` of the winning pair
            association (None for a mean or when not measured).
    """

    pipeline: str
    lda: PairAssociations
    rotation_consensus: ConsensusResult | None = None
    translation_consensus: ConsensusResult | None = None
    n_translation_pairs: int = 0
    used_prior: bool = False
    rotation_pair: np.ndarray | None = None
    translation_pair: np.ndarray | None = None

    def sources(self, status: Status) -> np.ndarray | None:
        """(S, 2) the plane associations (prev, curr) the winning pairs give: ``(i1, j1)``
        and ``(i2, j2)`` of the rotation pair and, when ``status`` is OK, of the
        translation pair; None when a DoF measured does not come from one pair."""
        pairs = [self.rotation_pair]
        if status is Status.OK:
            pairs.append(self.translation_pair)
        if any(p is None for p in pairs):
            return None
        # np.unique(rows, axis=0) of the (prev, curr) rows (sorted distinct), over the
        # two to four rows as Python integers: numpy's per-call overhead was the cost
        rows: set[tuple[int, int]] = set()
        for p in pairs:
            i1, i2, j1, j2 = np.asarray(p, dtype=int).reshape(4).tolist()
            rows.update(((i1, j1), (i2, j2)))
        return np.array(sorted(rows), dtype=int)


@dataclass(frozen=True, eq=False)
class RelativePose:
    """The pose of epoch ``curr`` relative to epoch ``prev`` (5-DoF measurement).

    Attributes:
        T_prev_curr: (4, 4) maps the current base frame to the previous one; its z is
            measured only when ``z_observed``.
        covariance: (5, 5) covariance of (roll, pitch, yaw, x, y), rad^2 and m^2, or None
            when unknown (the smoother then uses its defaults). DoF that were not measured
            (unresolved, degenerate) get the squared motion bound. From the solver: first-
            order propagation of the winning pairs' plane covariances
            (:func:`planodom.odometry.propagate.pose_covariance`), else the spread of the
            agreeing candidates, plus the floors ``odometry.min_sigma_*``.
        status: see :class:`Status`.
        associations: (L, 2) int strict plane associations (index in ``prev``'s planes,
            index in ``curr``'s) under the final pose; they track planes into landmarks.
        sources: (S, 2) int, (plane index in ``prev``, plane index in ``curr``), the
            associations it was computed from (the solver's winning rotation and
            translation pairs, :meth:`SolverDiagnostics.sources`); None when it does not
            derive from single pairs of the epochs' planes (a mean, an independent
            sensor). See ``SmoothingConfig.between_factors``.
        prev, curr: epoch indices (-1: not set, e.g. straight from the solver).
        z_observed: whether the vertical translation was measured (ground plane).
        sigma_z: standard deviation of the vertical translation, metres (inf: unobserved).
        diagnostics: how the solver found it (None for other sources).
        inconsistent: the solver found it degenerate but its angular rate disagreed with
            the constant-velocity prediction (``odometry.degenerate_gate``): the streaming
            odometry reports it unresolved and bridges it (``T_prev_curr`` is the bridge,
            ``covariance`` and ``diagnostics`` the solver's).
        rotation_partly_observed: the planes fixed only part of the rotation; about the
            other axes it is the constant-velocity prediction's, with its uncertainty in
            ``covariance`` (``planemap.partial_rotation``).
        time_spread: whether epoch ``curr``'s points were spread in time (its scan's times
            differ; False: taken at one instant, nothing to deskew), as the streaming
            odometry saw it, or as given to ``smoothing.run.relative_poses`` with the
            planes; None: not known (planes given alone, other sources).
        deskew_twist: (6,) the twist epoch ``curr``'s points were deskewed with (rad/s,
            m/s; None: not deskewed or not known); ``deskew_times``: (first, last) of its
            points' times relative to the epoch's (s; None: not spread or not known);
            ``interval_s``: ``curr``'s time less ``prev``'s (s; NaN: not known). The
            sandwich covariances estimate the deskewing error from them
            (:mod:`planodom.smoothing.deskew_scale`, :mod:`planodom.smoothing.undeskewed`).
    """

    T_prev_curr: np.ndarray
    covariance: np.ndarray | None
    status: Status = Status.OK
    associations: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.intp))
    sources: np.ndarray | None = None
    prev: int = -1
    curr: int = -1
    z_observed: bool = False
    sigma_z: float = np.inf
    diagnostics: SolverDiagnostics | None = None
    inconsistent: bool = False
    time_spread: bool | None = None
    rotation_partly_observed: bool = False
    deskew_twist: np.ndarray | None = None
    deskew_times: tuple[float, float] | None = None
    interval_s: float = np.nan

    def between(self, prev: int, curr: int) -> RelativePose:
        """The same relative pose labelled as between epochs ``prev`` and ``curr``."""
        return replaced(self, prev=prev, curr=curr)

    @property
    def delta(self) -> int:
        """Epoch gap ``curr - prev``."""
        return self.curr - self.prev

    @property
    def measured(self) -> bool:
        """Whether anything was measured (not unresolved): the smoother makes a factor."""
        return self.status is not Status.UNRESOLVED

    @property
    def translation_observed(self) -> bool:
        """Whether the horizontal translation was measured (else a rotation-only factor)."""
        return self.status is Status.OK

    @property
    def rpy(self) -> np.ndarray:
        """(roll, pitch, yaw) increments, rad."""
        return rpy_from_rotation(self.T_prev_curr[:3, :3])

    @property
    def pose5(self) -> np.ndarray:
        """(roll, pitch, yaw, x, y), rad and m."""
        return np.concatenate([self.rpy, self.T_prev_curr[:2, 3]])

    @property
    def sigmas5(self) -> np.ndarray:
        """(5,) standard deviations of (roll, pitch, yaw, x, y), rad and m (NaN: unknown)."""
        if self.covariance is None:
            return np.full(5, np.nan)
        return np.sqrt(np.diag(self.covariance))


_Replaced = TypeVar("_Replaced", SolverDiagnostics, RelativePose)


def replaced(obj: _Replaced, **changes: Any) -> _Replaced:
    """``dataclasses.replace(obj, **changes)`` for this module's frozen dataclasses (every
    field an ``__init__`` argument, no ``__post_init__``): a shallow copy with ``changes``
    set, without ``replace``'s per-field calls (the streaming odometry makes five an
    epoch pair). TypeError for a name that is no field, as ``replace``."""
    unknown = changes.keys() - obj.__dataclass_fields__.keys()
    if unknown:
        raise TypeError(f"{type(obj).__name__} has no field(s) {sorted(unknown)}")
    new = object.__new__(type(obj))
    new.__dict__.update(obj.__dict__)
    new.__dict__.update(changes)
    return new
