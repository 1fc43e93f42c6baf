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
        # Per triangle: its surface index, plane (n, d) and surface id.
        self._owner = np.append(owner.astype(np.int64), -1)  # last entry: no hit
        planes = np.column_stack([scene.normals, scene.offsets])[owner]
        self._planes = np.vstack([planes, [0.0, 0.0, 0.0, np.nan]])
        self._ids = np.append(scene.ids.astype(np.int32)[owner], np.int32(-1))
        self._no_hit = np.uint32(len(owner))  # index of the sentinel entries
        self._rs = o3d.t.geometry.RaycastingScene()
        self._rs.add_triangles(
            o3d.core.Tensor(verts.astype(np.float32)), o3d.core.Tensor(tris.astype(np.uint32))
        )

    def cast(
        self, origins: np.ndarray, directions: np.ndarray, max_range: float | np.ndarray = np.inf
    ) -> RayHits:
        """Cast rays from ``origins`` (N, 3) along unit ``directions`` (N, 3), world frame,
        metres (float64). Hits beyond ``max_range`` (scalar or (N,), metres) are no hits."""
        return self.cast_rays(np.hstack([origins, directions]), max_range)

    def cast_rays(self, rays: np.ndarray, max_range: float | np.ndarray = np.inf) -> RayHits:
        """:meth:`cast` for rays (N, 6) ``[origin, unit direction]``, float64, world frame."""
        rays = np.asarray(rays, dtype=np.float64)
        out = self._rs.cast_rays(
            o3d.core.Tensor.from_numpy(rays.astype(np.float32)), nthreads=self.nthreads
        )
        prim = np.minimum(out["primitive_ids"].numpy(), self._no_hit)  # invalid -> sentinel
        P = self._planes.take(prim, axis=0)
        nx, ny, nz = P[:, 0], P[:, 1], P[:, 2]
        num = nx * rays[:, 0] + ny * rays[:, 1] + nz * rays[:, 2] + P[:, 3]
        den = nx * rays[:, 3] + ny * rays[:, 4] + nz * rays[:, 5]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = -num / den  # float64 intersection with the hit surface's plane
            ok = (r > 0) & (r <= max_range)  # NaN (no hit, grazing) fails both
        prim = np.where(ok, prim, self._no_hit)  # beyond range -> sentinel too
        return RayHits(np.where(ok, r, np.inf), self._owner.take(prim), self._ids.take(prim))
