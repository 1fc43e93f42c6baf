"""A ringed scan's segmentation reused when it is extracted again with a nearby twist.

The streaming odometry extracts an epoch's scan with its predicted twist, then, when the
epoch's own twist differs, again with that one (:mod:`planodom.odometry.deskew`): 1.07-1.7
extractions an epoch on the indoor lidar worlds. Each segments the scan anew (ring noise,
range image or RANSAC loop: about half of an indoor extraction), though the two
deskewings move the points by millimetres. With ``extraction.segmentation_reuse:
near_twist`` the lidar path (:func:`planodom.extraction.lidar.path.lidar_planes`) takes
the last extraction's :class:`Segmentation` (its candidate inlier sets, noise sigma and
the agreement check's pixel normals) for the very scan extracted last (the same arrays,
an equal config and viewpoint) when the new twist moves no point by more than the
member tolerance from where the last one put it: to first order a point ``p`` at time
``t`` moves by ``t (dw x p + dv)``, at most ``max |t| (|dw| max |p| + |dv|)``. A member
then lies within twice the tolerance of its plane, and no point of another surface
comes nearer than the tolerance did; the candidates are fitted again to the newly
deskewed points with the robust fit, which selects their inliers anew (1.4826 MAD), and
built again (plane builder), so the planes take the new twist. (Half the tolerance
reused 22 of 41 re-extractions on the dev world 153 at 6 mm, none on 173: an epoch's
twist is refined by 0.5-1.5 deg/s, which moves a point 26-45 m away by 6-30 mm over
the 25 ms of a centred 20 Hz sweep.)

One entry, keyed like :func:`planodom.extraction.memo.identity_memo` (weak references to
the scan's arrays): it never keeps a scan alive, and another scan replaces it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.epoch import Epoch
from planodom.extraction.lidar.agreement import PointNormals
from planodom.extraction.memo import key_part, same_args
from planodom.extraction.noise import member_tolerance

#: The largest point motion between the two deskewings, as a share of the member tolerance.
REUSE_SHARE = 1.0


@dataclass(eq=False)
class Segmentation:
    """One extraction's segmentation of a ringed scan.

    Attributes:
        candidates: candidate inlier sets, (K_i,) int64 indices into the scan's points.
        sigma: the noise sigma (m) the tolerances were scaled with.
        ransac: whether the RANSAC loop found them (else the range image).
        twist: (6,) the twist the points were deskewed with (zeros: not deskewed).
    """

    candidates: list[np.ndarray]
    sigma: float
    ransac: bool
    twist: np.ndarray
    _normals: list[PointNormals | None] = field(default_factory=list)

    def agreement_normals(self, compute: Callable[[], PointNormals | None]) -> PointNormals | None:
        """The agreement check's pixel normals (:mod:`.agreement`): ``compute()`` the first
        time, then the same."""
        if not self._normals:
            self._normals.append(compute())
        return self._normals[0]


@dataclass(eq=False)
class _Entry:
    """The last segmentation and what it was made of (arrays by weak reference)."""

    arrays: list[tuple[bool, Any]]  # memo.key_part of the raw points, times and ring
    config: ExtractionConfig
    view: np.ndarray
    found: Segmentation
    reach: tuple[float, float] | None = None  # (max |t| s, max |p| m) of the raw scan


_LAST: list[_Entry | None] = [None]


def _scan_arrays(epoch: Epoch, ring: np.ndarray | None) -> tuple[np.ndarray | None, ...]:
    """The arrays a segmentation is made of: the raw points, times and ring."""
    return (epoch.scan.points, epoch.scan.t, ring)


def reused(
    epoch: Epoch, ring: np.ndarray | None, view: np.ndarray, config: ExtractionConfig
) -> Segmentation | None:
    """The last extraction's segmentation for ``epoch`` (with ``ring`` (N,), seen from
    ``view`` (3,) m) when ``config.segmentation_reuse`` allows it (module docstring);
    None: segment anew."""
    entry = _LAST[0]
    if config.segmentation_reuse == "off" or entry is None or epoch.scan.t is None:
        return None
    if not same_args(entry.arrays, _scan_arrays(epoch, ring)):
        return None
    if not np.array_equal(entry.view, view) or entry.config != config:
        return None
    if entry.reach is None:
        t, p = epoch.scan.t, epoch.scan.points
        p_max = float(np.sqrt(np.max(np.einsum("ij,ij->i", p, p)))) if len(p) else 0.0
        entry.reach = (float(np.max(np.abs(t))) if len(t) else 0.0, p_max)
    twist = np.zeros(6) if epoch.twist is None else np.asarray(epoch.twist, dtype=np.float64)
    d = twist - entry.found.twist
    t_max, p_max = entry.reach
    moved = t_max * (float(np.linalg.norm(d[:3])) * p_max + float(np.linalg.norm(d[3:])))
    if not moved <= REUSE_SHARE * member_tolerance(config, entry.found.sigma):
        return None
    return entry.found


def remembered(
    epoch: Epoch,
    ring: np.ndarray | None,
    view: np.ndarray,
    config: ExtractionConfig,
    candidates: list[np.ndarray],
    sigma: float,
    ransac: bool,
) -> Segmentation:
    """The :class:`Segmentation` of these candidates (indices into ``epoch``'s points),
    ``sigma`` (m) and ``ransac``, kept for :func:`reused` when
    ``config.segmentation_reuse`` is on."""
    twist = np.zeros(6) if epoch.twist is None else np.array(epoch.twist, dtype=np.float64)
    found = Segmentation(candidates, float(sigma), bool(ransac), twist)
    if config.segmentation_reuse != "off":
        parts = [key_part(a) for a in _scan_arrays(epoch, ring)]
        _LAST[0] = _Entry(parts, config, np.array(view, dtype=np.float64), found)
    return found
