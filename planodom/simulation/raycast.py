"""Ray casting against a :class:`Scene` with open3d's Embree ``RaycastingScene``.

Embree works in float32 (hits good to about 1e-5 relative). Each hit is refined in
float64 by intersecting the float64 ray with the float64 plane of the surface Embree
reports, so that noise-free points lie on their surface's plane to about 1e-12 m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom._open3d import o3d
from planodom.simulation.scene import Scene

#: Id Embree reports for rays that hit nothing.
_INVALID = o3d.t.geometry.RaycastingScene.INVALID_ID


@dataclass(frozen=True, eq=False)
class RayHits:
    """Result of casting N rays.

    Attributes:
        ranges: (N,) float64 distances along the unit rays, metres; inf for no hit.
        surface: (N,) int64 index into ``scene.surfaces``; -1 for no hit.
        labels: (N,) int32 surface id; -1 for no hit.
    """

    ranges: np.ndarray
    surface: np.ndarray
    labels: np.ndarray


class RayCaster:
    """Build the Embree scene of ``scene`` once; cast batches of rays with :meth:`cast`.

    Args:
        scene: the surfaces (fan-triangulated; triangle -> surface index kept).
        nthreads: Embree threads (0: all cores).
    """

    def __init__(self, scene: Scene, nthreads: int = 0) -> None:
        self.scene = scene
        self.nthreads = nthreads
        verts, tris, owner = scene.triangles()
        self._owner = owner.astype(np.int64)
        self._planes = np.column_stack([scene.normals, scene.offsets])  # (K, 4)
        self._ids = scene.ids.astype(np.int32)
        self._rs = o3d.t.geometry.RaycastingScene()
        self._rs.add_triangles(
            o3d.core.Tensor(verts.astype(np.float32)), o3d.core.Tensor(tris.astype(np.uint32))
        )

    def cast(
        self, origins: np.ndarray, directions: np.ndarray, max_range: float | np.ndarray = np.inf
    ) -> RayHits:
        """Cast rays from ``origins`` (N, 3) along unit ``directions`` (N, 3), world frame,
        metres (float64). Hits beyond ``max_range`` (scalar or (N,), metres) are no hits."""
        n = len(origins)
        rays = np.empty((n, 6), dtype=np.float32)
        rays[:, :3], rays[:, 3:] = origins, directions
        out = self._rs.cast_rays(o3d.core.Tensor.from_numpy(rays), nthreads=self.nthreads)
        prim = out["primitive_ids"].numpy()
        hit = np.flatnonzero(prim != _INVALID)
        surf = self._owner.take(prim.take(hit))
        P = self._planes.take(surf, axis=0)
        o, d = origins.take(hit, axis=0), directions.take(hit, axis=0)
        num = P[:, 0] * o[:, 0] + P[:, 1] * o[:, 1] + P[:, 2] * o[:, 2] + P[:, 3]
        den = P[:, 0] * d[:, 0] + P[:, 1] * d[:, 1] + P[:, 2] * d[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = -num / den  # float64 intersection with the hit surface's plane
        rmax = max_range if np.ndim(max_range) == 0 else np.take(max_range, hit)
        ok = (r > 0) & (r <= rmax)  # also drops NaN from (impossible) grazing hits
        hit, surf, r = hit[ok], surf[ok], r[ok]
        ranges = np.full(n, np.inf)
        ranges[hit] = r
        surface = np.full(n, -1, dtype=np.int64)
        surface[hit] = surf
        labels = np.full(n, -1, dtype=np.int32)
        labels[hit] = self._ids.take(surf)
        return RayHits(ranges, surface, labels)
