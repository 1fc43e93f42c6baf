"""The planes of one epoch as one set of arrays: :class:`PlaneSet`.

A plane is ``n . p + d = 0`` (unit normal n, offset d in metres; measured normals point
towards the sensor), as ``gtsam.OrientedPlane3``. It appears in four forms, each where it
serves, with these conversions:

============================== ===================================== ======================
form                           where                                 conversion
============================== ===================================== ======================
:class:`planodom.geometry.Plane` one measured plane with its quality  ``Plane.coefficients``
                               (covariance, confidence, support)     -> (4,)
:class:`PlaneSet`              all planes of an epoch as arrays      ``PlaneSet.from_planes``
                               (association, consensus, odometry)    ``.coefficients`` (K, 4)
(4,) ``[nx, ny, nz, d]``       the factor graph's bookkeeping        ``Plane(c[:3], c[3])``
``gtsam.OrientedPlane3``       factor-graph variables and factors    ``OrientedPlane3(c)``,
                                                                     ``.planeCoefficients()``
============================== ===================================== ======================
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from planodom.errors import GeometryError
from planodom.geometry import Plane, plane_transform_jacobian, transform_planes, transform_points

#: The rows of an unknown covariance and centroid.
_NAN44 = np.full((4, 4), np.nan)
_NAN3 = np.full(3, np.nan)


@dataclass(frozen=True, eq=False)
class PlaneSet:
    """The planes of one epoch as arrays, what association, consensus and odometry need.

    Attributes:
        normals: (K, 3) float64 unit normals. offsets: (K,) metres.
        weights: (K,) confidences in (0, 1].
        centroids: (K, 3) support centroids, metres (NaN rows when unknown).
        radii: (K,) largest distance from centroid to support polygon vertex, metres
            (NaN when the polygon is unknown).
        covariances: (K, 4, 4) covariances of ``(n, d)`` (NaN when unknown).
        narrow: (K,) bool, :attr:`planodom.geometry.Plane.narrow`; None: none is.
    """

    normals: np.ndarray
    offsets: np.ndarray
    weights: np.ndarray
    centroids: np.ndarray
    radii: np.ndarray
    covariances: np.ndarray
    narrow: np.ndarray | None = None

    @classmethod
    def from_planes(cls, planes: Sequence[Plane]) -> PlaneSet:
        """The arrays of a list of :class:`Plane` (in that order); GeometryError for an
        item that is no Plane (e.g. the rows of an (N, 3) array of points given as an
        epoch, which ended in an AttributeError). The set an extraction built with these
        very planes is returned when it was handed over (:func:`hand_over`)."""
        ready = _handed(planes)
        if ready is not None:
            return ready
        bad = next((p for p in planes if not isinstance(p, Plane)), None)
        if bad is not None:
            raise GeometryError(
                f"expected planodom.Plane objects, got {type(bad).__name__}; an epoch's "
                "points go in as a planodom.Scan (register_epoch, run_odometry)"
            )
        k = len(planes)
        if k == 0:
            z = np.zeros(0)
            return cls(
                np.zeros((0, 3)), z, z.copy(), np.zeros((0, 3)), z.copy(), np.zeros((0, 4, 4))
            )
        normals = np.array([p.normal for p in planes], dtype=np.float64)
        offsets = np.array([p.offset for p in planes], dtype=np.float64)
        weights = np.array([p.confidence for p in planes], dtype=np.float64)
        # one conversion of the rows each (setting them one by one cost more)
        covariances = np.array(
            [_NAN44 if p.covariance is None else p.covariance for p in planes], dtype=np.float64
        ).reshape(k, 4, 4)
        supports = [p.support for p in planes]
        centroids = np.array(
            [_NAN3 if q is None else q.centroid for q in supports], dtype=np.float64
        ).reshape(k, 3)
        polygons = [None if q is None else q.polygon for q in supports]
        narrow = np.array([p.narrow for p in planes], dtype=bool)
        return cls.from_arrays(normals, offsets, weights, covariances, centroids, polygons, narrow)

    @classmethod
    def from_arrays(
        cls, normals: np.ndarray, offsets: np.ndarray, weights: np.ndarray,
        covariances: np.ndarray, centroids: np.ndarray, polygons: Sequence[np.ndarray | None],
        narrow: np.ndarray,
    ) -> PlaneSet:  # fmt: skip
        """The set of K planes from their fields stacked (the arrays are taken, not
        copied; ``narrow`` (K,) bool) and their support ``polygons`` (None or (0, 3):
        unknown), whose farthest vertices from the centroids give the radii."""
        radii = np.full(len(offsets), np.nan)
        owners = [i for i, q in enumerate(polygons) if q is not None and len(q)]
        if owners:  # the farthest vertex, all planes at once (np.linalg.norm's arithmetic)
            held = [polygons[i] for i in owners]
            sizes = np.array([len(q) for q in held], dtype=np.int64)  # type: ignore[arg-type]
            verts = np.concatenate(held).astype(np.float64, copy=False)  # type: ignore[arg-type]
            radii[owners] = _radii_kernel(verts, centroids[owners], sizes)
        return cls(
            normals, offsets, weights, centroids, radii, covariances,
            narrow if narrow.any() else None,
        )  # fmt: skip

    def __len__(self) -> int:
        return len(self.offsets)

    @property
    def coefficients(self) -> np.ndarray:
        """(K, 4) ``[nx, ny, nz, d]`` per plane."""
        return np.column_stack([self.normals, self.offsets])

    def transformed(self, T_a_b: np.ndarray) -> PlaneSet:
        """These planes (in frame b) expressed in frame a; covariances follow."""
        n, d = transform_planes(T_a_b, self.normals, self.offsets)
        J = plane_transform_jacobian(T_a_b)
        cov = J @ self.covariances @ J.T
        centroids = transform_points(T_a_b, self.centroids)
        return PlaneSet(n, d, self.weights, centroids, self.radii, cov, self.narrow)

    def take(self, index: np.ndarray) -> PlaneSet:
        """The planes at ``index`` (int array or mask), in that order."""
        return PlaneSet(
            self.normals[index],
            self.offsets[index],
            self.weights[index],
            self.centroids[index],
            self.radii[index],
            self.covariances[index],
            None if self.narrow is None else self.narrow[index],
        )


#: The set an extraction built with its planes, for the next ``from_planes`` of them:
#: [the planes (a tuple), the set], or [None, None].
_HANDED: list = [None, None]


def hand_over(planes: Sequence[Plane], plane_set: PlaneSet) -> None:
    """Leave ``plane_set``, the arrays of ``planes`` built with them (what
    :meth:`PlaneSet.from_planes` would give), to the next ``from_planes`` call, which
    returns it if that call is given these very plane objects in this order (the
    odometry's, right after the extraction) and drops it either way: a set is handed to
    one caller at most, as ``from_planes`` gives each a set of its own."""
    _HANDED[0], _HANDED[1] = tuple(planes), plane_set


def reorder_handed(planes: Sequence[Plane], order: Sequence[int]) -> None:
    """The set handed over with ``planes`` (:func:`hand_over`), if it is, handed over
    again with the planes in ``order`` (K,) (the extraction's largest-first order)."""
    held, ready = _HANDED
    if held is None or not _same_objects(held, planes):
        return
    if list(order) != list(range(len(planes))):
        ready = ready.take(np.asarray(order, dtype=np.int64))
    hand_over([planes[i] for i in order], ready)


def _handed(planes: Sequence[Plane]) -> PlaneSet | None:
    """The set handed over with these very ``planes`` (None: none was), dropped."""
    held, ready = _HANDED
    if held is None:
        return None
    _HANDED[0] = _HANDED[1] = None
    return ready if _same_objects(held, planes) else None


def _same_objects(a: Sequence[object], b: Sequence[object]) -> bool:
    """Whether ``a`` and ``b`` hold the same objects (identity) in the same order."""
    return len(a) == len(b) and all(x is y for x, y in zip(a, b, strict=True))


def as_plane_set(planes: Sequence[Plane] | PlaneSet) -> PlaneSet:
    """A list of :class:`Plane` as a :class:`PlaneSet`; a ready set unchanged."""
    return planes if isinstance(planes, PlaneSet) else PlaneSet.from_planes(planes)


@numba.njit(cache=True)
def _radii_kernel(verts, centroids, sizes):  # pragma: no cover - compiled
    """(G,) the largest distance, m, from each centroid (G, 3) to its polygon's vertices:
    ``verts`` (M, 3), the polygons one after another, ``sizes`` (G,) int64 their vertex
    counts (each at least 1). The arithmetic of ``np.sqrt(np.max(((v - c) ** 2).sum(axis=1)))``
    (a row's squares summed left to right, as numpy's reduction over three elements: the
    same bits), one compiled call instead of six numpy calls a plane set."""
    out = np.empty(sizes.shape[0])
    k = 0
    for g in range(sizes.shape[0]):
        best = -np.inf
        for _ in range(sizes[g]):
            a = verts[k, 0] - centroids[g, 0]
            b = verts[k, 1] - centroids[g, 1]
            c = verts[k, 2] - centroids[g, 2]
            s = a * a + b * b + c * c
            if s > best or s != s:  # NaN propagates as np.maximum does
                best = s
            k += 1
        out[g] = np.sqrt(best)
    return out
