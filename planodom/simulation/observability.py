"""Which surfaces a scan observes as planes: counted from labels and ring ids.

A *trace* is the set of points of one ring (one 2D scanner) on one surface in one epoch
(all its sweeps), summarised by its principal direction. Points are taken in the base
frame at their own time, where every point of a 2D scanner lies in its scan plane, so a
trace is a straight segment even while the vehicle moves. A surface is *observable as a
plane* when it has two traces whose directions differ by more than ``min_angle_deg``
(the brief's RIG.md). Walls are the surfaces of kind wall / facade; the ground is
reported on its own (it is also determined by two distinct parallel traces).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.scan import Scan
from planodom.simulation.scene import VERTICAL_KINDS, Scene


@dataclass(frozen=True)
class RingTraces:
    """Traces of one scan: per trace its surface id (K,), ring (K,), point count (K,),
    unit direction (K, 3) and length (K,) in metres (sqrt(12) x the principal std)."""

    label: np.ndarray
    ring: np.ndarray
    count: np.ndarray
    direction: np.ndarray
    length: np.ndarray


def ring_traces(scan: Scan, min_points: int = 5, min_length: float = 0.5) -> RingTraces:
    """The traces of ``scan`` with at least ``min_points`` points and ``min_length`` m."""
    if scan.label is None or scan.ring is None:
        raise ValueError("observability needs a scan with labels and rings")
    keep = scan.label >= 0
    key = scan.label[keep].astype(np.int64) * 100_000 + scan.ring[keep]
    keys, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    p = scan.points[keep]
    mean = np.stack([np.bincount(inv, p[:, i]) for i in range(3)], axis=1) / count[:, None]
    q = p - mean[inv]
    outer = q[:, :, None] * q[:, None, :]
    cov = np.stack([np.bincount(inv, outer[:, i, j]) for i in range(3) for j in range(3)], axis=1)
    w, v = np.linalg.eigh(cov.reshape(-1, 3, 3) / count[:, None, None])
    length = np.sqrt(12.0 * np.maximum(w[:, 2], 0.0))
    ok = (count >= min_points) & (length >= min_length)
    return RingTraces(keys[ok] // 100_000, keys[ok] % 100_000, count[ok], v[ok, :, 2], length[ok])


@dataclass(frozen=True)
class EpochObservability:
    """Per epoch: ids of walls hit (any trace), walls observable as planes, the number of
    pairs of observable walls with non-parallel normals, and whether the ground is."""

    walls_hit: tuple[int, ...]
    walls_observable: tuple[int, ...]
    n_pairs: int
    ground_observable: bool


def _crossing(directions: np.ndarray, sin_min: float) -> bool:
    c = np.linalg.norm(np.cross(directions[:, None], directions[None]), axis=-1)
    return bool(np.any(c > sin_min))


def epoch_observability(
    scan: Scan,
    scene: Scene,
    min_angle_deg: float = 10.0,
    min_points: int = 5,
    min_length: float = 0.5,
) -> EpochObservability:
    """Observability of the surfaces of ``scene`` in one ``scan`` (see module docstring)."""
    tr = ring_traces(scan, min_points, min_length)
    sin_min = np.sin(np.deg2rad(min_angle_deg))
    hit, observable, ground_ok = [], [], False
    for lab in np.unique(tr.label):
        surface = scene.by_id(int(lab))
        d = tr.direction[tr.label == lab]
        crossing = len(d) >= 2 and _crossing(d, sin_min)
        if surface.kind in VERTICAL_KINDS:
            hit.append(int(lab))
            if crossing:
                observable.append(int(lab))
        elif surface.kind == "ground":
            ground_ok = ground_ok or len(d) >= 2
    normals = np.array([scene.by_id(i).normal for i in observable]).reshape(-1, 3)
    c = np.linalg.norm(np.cross(normals[:, None], normals[None]), axis=-1)
    n_pairs = int(np.count_nonzero(np.triu(c > sin_min, k=1)))
    return EpochObservability(tuple(hit), tuple(observable), n_pairs, ground_ok)


@dataclass(frozen=True)
class ObservabilityStats:
    """Per-epoch counts (E,) over a run: walls hit, walls observable, non-parallel pairs
    of observable walls, ground observable (bool)."""

    walls_hit: np.ndarray
    walls_observable: np.ndarray
    pairs: np.ndarray
    ground: np.ndarray

    def summary(self) -> dict[str, tuple[float, float, float]]:
        """(min, median, max) of each count."""
        return {
            name: (float(a.min()), float(np.median(a)), float(a.max()))
            for name, a in (
                ("walls_hit", self.walls_hit),
                ("walls_observable", self.walls_observable),
                ("pairs", self.pairs),
            )
        }


def observability(scans, scene: Scene, **kwargs) -> ObservabilityStats:
    """:func:`epoch_observability` over a sequence of scans (e.g. a ``SimulatedRun``)."""
    per = [epoch_observability(s, scene, **kwargs) for s in scans]
    return ObservabilityStats(
        np.array([len(e.walls_hit) for e in per]),
        np.array([len(e.walls_observable) for e in per]),
        np.array([e.n_pairs for e in per]),
        np.array([e.ground_observable for e in per]),
    )
