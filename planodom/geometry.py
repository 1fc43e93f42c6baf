"""Geometry shared by every stage: planes, rigid transforms, frames and reference points.

Conventions (kept everywhere in planodom):

- A plane is a unit normal ``n`` and an offset ``d`` with ``n . p + d = 0`` for every point
  ``p`` on it, the convention of ``gtsam.OrientedPlane3``. Measured planes have normals
  pointing towards the sensor, so ``d > 0`` for a plane that does not pass through the
  sensor origin (the origin is on the positive side: ``n . 0 + d = d > 0``).
- ``T_a_b`` is a 4x4 homogeneous transform taking coordinates in frame ``b`` to frame ``a``:
  ``p_a = T_a_b @ p_b``. ``T_world_base`` is the pose of the vehicle base in the world.
- SI units inside: metres and radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numba
import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from planodom.errors import GeometryError
from planodom.orthonormality import is_orthonormal

# re-exported: the SE(3) maps were split to planodom.se3
from planodom.se3 import cross_rows as cross_rows
from planodom.se3 import se3_exp as se3_exp
from planodom.se3 import se3_log as se3_log
from planodom.se3 import twist_step as twist_step

#: Unit vector of the vertical axis of a base frame (z up).
UP = np.array([0.0, 0.0, 1.0])

#: Largest deviation of ``R^T R`` from the identity (per entry) of a 3x3 block that counts as
#: a rotation where one is read from a file or given in code (a KITTI pose or ``Tr``, a
#: ``rig.yaml`` extrinsic, a simulated sensor's ``T_base_sensor``). Files written with 6
#: decimals are off by ~1e-6 (KITTI writes 6 to 12 significant digits), four decimals
#: (0.7071) by ~1e-4; the same bound as a TUM quaternion's norm
#: (``planodom.datasets.tum.QUATERNION_NORM_TOL``). A scaled, sheared or singular block (a
#: projection matrix, a typo) is refused, not used as a pose.
ROTATION_TOL = 1e-3


# --------------------------------------------------------------------------- transforms


def vector_norm(v: np.ndarray) -> float:
    """``np.linalg.norm`` of a 1-D float64 array ``v`` (its arithmetic: the square root of
    ``v.dot(v)``, the same bits), without its per-call overhead (a few microseconds, a
    few thousand calls a run of the streaming odometry)."""
    return math.sqrt(v.dot(v))


def row_norms(x: np.ndarray) -> np.ndarray:
    """(N,) ``np.linalg.norm(x, axis=1)`` of ``x`` (N, 3), the same bits (numpy's sum over a
    row of three: ``(x0^2 + x1^2) + x2^2``, checked on every memory layout), without its
    reduction over a short axis, ~9x slower on a lidar sweep's points; other shapes go
    to numpy."""
    if x.ndim != 2 or x.shape[1] != 3 or x.dtype.kind != "f":
        return np.linalg.norm(x, axis=1)
    return np.sqrt((x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1]) + x[:, 2] * x[:, 2])


def make_transform(R: np.ndarray, t: ArrayLike) -> np.ndarray:
    """Build ``T`` (4, 4) from a rotation ``R`` (3, 3) and a translation ``t`` (3,), metres."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, dtype=float).reshape(3)
    return T


def non_rotations(R: ArrayLike) -> np.ndarray:
    """Indices of the (E, 3, 3) blocks ``R`` that are no rotation: ``R^T R`` off the identity
    by more than :data:`ROTATION_TOL` in an entry, a reflection (determinant < 0), or not
    finite."""
    R = np.asarray(R, dtype=np.float64).reshape(-1, 3, 3)
    finite = np.all(np.isfinite(R), axis=(1, 2))
    R = np.where(finite[:, None, None], R, 0.0)
    gram = np.einsum("eji,ejk->eik", R, R) - np.eye(3)
    off = np.abs(gram).max(axis=(1, 2)) > ROTATION_TOL
    return np.flatnonzero(off | (np.linalg.det(R) < 0) | ~finite)


def rotation_problem(R: ArrayLike) -> str | None:
    """Why the (3, 3) ``R`` is no rotation (see :func:`non_rotations`), in a few words; None
    for a rotation."""
    R = np.asarray(R, dtype=np.float64)
    if not len(non_rotations(R)):
        return None
    if not np.all(np.isfinite(R)):
        return "its 3x3 part is not finite"
    scales = np.linalg.norm(R, axis=0)
    if not np.allclose(scales, 1.0, rtol=0.0, atol=ROTATION_TOL):
        return f"its 3x3 part has column norms {', '.join(f'{v:.6g}' for v in scales)}, not 1"
    if np.linalg.det(R) < 0:
        return "its 3x3 part is a reflection, determinant < 0"
    return "the columns of its 3x3 part are not orthogonal"


def first_non_rotation(R: ArrayLike) -> tuple[int, str, int] | None:
    """Of the (E, 3, 3) blocks ``R``, the index of the first that is no rotation
    (:func:`non_rotations`), why (:func:`rotation_problem`) and how many are not; None
    when all are rotations."""
    R = np.asarray(R, dtype=np.float64).reshape(-1, 3, 3)
    bad = non_rotations(R)
    if not len(bad):
        return None
    k = int(bad[0])
    return k, rotation_problem(R[k]) or "", len(bad)


def invert_transform(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms ``T`` (..., 4, 4) (``T_b_a`` from ``T_a_b``) in closed form."""
    T = np.asarray(T, dtype=np.float64)
    R_t = np.swapaxes(T[..., :3, :3], -1, -2)
    inv = np.zeros_like(T)
    inv[..., :3, :3] = R_t
    inv[..., :3, 3] = -(R_t @ T[..., :3, 3, None])[..., 0]
    inv[..., 3, 3] = 1.0
    return inv


def transform_points(T_a_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Map ``points_b`` (N, 3), metres, in frame b to frame a; returns (N, 3)."""
    return points_b @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def transform_from_rpy_xyz(
    roll: float, pitch: float, yaw: float, x: float, y: float, z: float = 0.0
) -> np.ndarray:
    """``T`` (4, 4) from roll, pitch, yaw (rad), ``R = Rz(yaw) Ry(pitch) Rx(roll)``, and xyz (m)."""
    R = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
    return make_transform(R, [x, y, z])


def rpy_from_rotation(R: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw), radians, of rotations ``R`` (..., 3, 3) = Rz(yaw) Ry(pitch) Rx(roll).

    Returns (..., 3): (3,) for one rotation. scipy's ZYX Euler angles (gimbal-lock aware).
    """
    R = np.asarray(R, dtype=np.float64)
    M = R.reshape(-1, 3, 3)
    ypr = Rotation.from_matrix(M, assume_valid=_surely_rotations(M)).as_euler("ZYX")
    return ypr[:, ::-1].reshape(R.shape[:-2] + (3,))


def _surely_rotations(M: np.ndarray) -> bool:
    """Whether scipy's ``Rotation.from_matrix`` would take every matrix of ``M`` (K, 3, 3)
    as it is: right-handed and ``M M^T`` within 1e-12 of the identity (``isclose``), else
    it projects it on SO(3) (SVD). Checked here ten times tighter (the two products may
    differ by rounding), so that ``assume_valid`` skips only checks that would pass, for
    the same angles at a quarter of the time (scipy's checks cost ~0.1 ms a call)."""
    gram = M @ np.swapaxes(M, 1, 2)
    close = np.abs(gram - np.eye(3)) <= 1e-13 + 1e-6 * np.eye(3)
    return bool(close.all() and (np.linalg.det(M) > 0.5).all())


def pose5_from_transform(T: np.ndarray) -> np.ndarray:
    """The 5 observed DoF (roll, pitch, yaw, x, y), rad and m, of relative transforms.

    ``T`` (..., 4, 4) -> (..., 5): (5,) for one transform.
    """
    T = np.asarray(T, dtype=np.float64)
    return np.concatenate([rpy_from_rotation(T[..., :3, :3]), T[..., :2, 3]], axis=-1)


def orthonormalised(T: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """``T`` (4, 4) with its rotation projected on SO(3) (SVD) once rounding exceeds ``tol``."""
    R = T[:3, :3]
    if is_orthonormal(R, tol):  # np.max(np.abs(R.T @ R - np.eye(3))) <= tol, compiled
        return T
    U, _, Vt = np.linalg.svd(R)
    out = T.copy()
    out[:3, :3] = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return out


# --------------------------------------------------------------------------- planes


@dataclass(frozen=True, eq=False)
class PlaneSupport:
    """What was seen of a plane: its inlier points summarised.

    Attributes:
        centroid: (3,) float64, metres, mean of the inlier points.
        polygon: (M, 3) float64, metres, convex hull of the inliers projected on the plane,
            vertices in order (M >= 3; empty (0, 3) when unknown).
        n_points: number of inlier points.
        scatter: (3, 3) float64, m^2, centred scatter ``sum (p_i - c)(p_i - c)^T`` of the
            inliers (with ``n_points`` and ``centroid`` their moments: what a
            point-to-plane cost over all inliers needs,
            :mod:`planodom.odometry.planemap.moments`), or None when unknown.
        n_rows: number of distinct scan lines (rings or recovered rows) among the inliers
            (0: unknown); a per-laser range bias is shared by the points of one line.
        time_moments: (5, 4, 4) float64 ``sum_i t_i^k h_i h_i^T``, k = 0..4, over the
            inliers, ``h_i = (p_i - centroid, 1)`` (m, s: ``t_i`` the point's time relative
            to the epoch's reference time), or None when unknown (points without times, or
            ``extraction.time_moments`` off): what the continuous-time registration needs
            (:mod:`planodom.odometry.planemap.ctreg`).
    """

    centroid: np.ndarray
    polygon: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    n_points: int = 0
    scatter: np.ndarray | None = None
    n_rows: int = 0
    time_moments: np.ndarray | None = None

    def transformed(self, T_a_b: np.ndarray) -> PlaneSupport:
        """The same support in frame a, given it in frame b."""
        poly = transform_points(T_a_b, self.polygon) if len(self.polygon) else self.polygon
        R = T_a_b[:3, :3]
        scatter = None if self.scatter is None else R @ self.scatter @ R.T
        centroid = transform_points(T_a_b, self.centroid[None])[0]
        moments = None
        if self.time_moments is not None:  # centred: only the rotation acts
            A = np.eye(4)
            A[:3, :3] = R
            moments = A @ self.time_moments @ A.T
        return PlaneSupport(centroid, poly, self.n_points, scatter, self.n_rows, moments)

    @property
    def area(self) -> float:
        """Area (m^2) of the support polygon (0 when unknown)."""
        if len(self.polygon) < 3:
            return 0.0
        v = self.polygon - self.polygon[0]
        return float(0.5 * np.linalg.norm(np.cross(v[1:-1], v[2:]).sum(axis=0)))


@dataclass(frozen=True, eq=False)
class Plane:
    """An oriented plane ``n . p + d = 0`` with what is known of its quality and extent.

    Attributes:
        normal: (3,) float64, unit normal; for measured planes it points towards the sensor.
        offset: ``d``, metres.
        covariance: (4, 4) float64 covariance of ``(nx, ny, nz, d)`` from the fit (rank 3:
            no variance along ``n`` itself), or None when unknown.
        confidence: weight in (0, 1]; higher is better (see :mod:`planodom.extraction`).
        support: inlier extent and centroid, or None.
        truth_id: id of the true surface in simulated data (-1 when unknown).
        deskew_jacobian: (4, 6) float64 first-order change of ``(nx, ny, nz, d)`` when the
            points were deskewed with a twist off by ``(dw, dv)`` over the epoch's time
            span (rad, m: the motion change over the span), or None when unknown (points
            without times) (:func:`planodom.extraction.planes.fit.deskew_jacobian`).
        narrow: its scanners' lines cross under ``min_cross_angle_deg`` (2D rig, marked
            with ``extraction.narrow_seed_last_deg``; :mod:`planodom.extraction.rig2d.narrow`).
    """

    normal: np.ndarray
    offset: float
    covariance: np.ndarray | None = None
    confidence: float = 1.0
    support: PlaneSupport | None = None
    truth_id: int = -1
    deskew_jacobian: np.ndarray | None = None
    narrow: bool = False

    def __post_init__(self) -> None:
        n = np.asarray(self.normal, dtype=np.float64).reshape(-1)
        if n.shape != (3,):
            raise GeometryError(f"plane normal must be 3 finite numbers, got {self.normal!r}")
        sq = float(n.dot(n))  # finite only if every component is: the full check otherwise
        if not math.isfinite(sq) and not np.isfinite(n).all():
            raise GeometryError(f"plane normal must be 3 finite numbers, got {self.normal!r}")
        norm = math.sqrt(sq)  # np.linalg.norm's arithmetic, without its overhead
        if norm < 1e-12:
            raise GeometryError("plane normal has zero length")
        if not math.isfinite(self.offset):
            raise GeometryError(f"plane offset must be finite, got {self.offset!r}")
        if not 0.0 < self.confidence <= 1.0:
            raise GeometryError(f"plane confidence must lie in (0, 1], got {self.confidence!r}")
        object.__setattr__(self, "normal", n / norm)
        object.__setattr__(self, "offset", float(self.offset) / norm)

    @property
    def coefficients(self) -> np.ndarray:
        """(4,) ``[nx, ny, nz, d]``."""
        return np.append(self.normal, self.offset)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distances (N,), metres, of ``points`` (N, 3); positive on the normal's side."""
        return np.asarray(points) @ self.normal + self.offset

    def transformed(self, T_a_b: np.ndarray) -> Plane:
        """This plane (given in frame b) expressed in frame a; covariance and support follow."""
        n, d = transform_planes(T_a_b, self.normal[None], np.array([self.offset]))
        cov, dsk = None, None
        J = plane_transform_jacobian(T_a_b)
        if self.covariance is not None:
            cov = J @ self.covariance @ J.T
        if self.deskew_jacobian is not None:
            dsk = J @ self.deskew_jacobian
        support = self.support.transformed(T_a_b) if self.support is not None else None
        return replace(
            self, normal=n[0], offset=float(d[0]), covariance=cov, support=support,
            deskew_jacobian=dsk,
        )  # fmt: skip

    def flipped(self) -> Plane:
        """The same plane with the opposite orientation (``-n, -d``)."""
        dsk = None if self.deskew_jacobian is None else -self.deskew_jacobian
        return replace(self, normal=-self.normal, offset=-self.offset, deskew_jacobian=dsk)

    def oriented_towards(self, point: np.ndarray) -> Plane:
        """This plane with its normal turned so that ``point`` (3,) lies on its positive side."""
        return self.flipped() if self.distance(np.asarray(point)[None])[0] < 0 else self

    def closest_point(self) -> np.ndarray:
        """(3,) the point of the plane closest to the origin, ``-d n``."""
        return -self.offset * self.normal


def transform_planes(
    T_a_b: np.ndarray, normals_b: np.ndarray, offsets_b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Express planes given in frame b in frame a.

    Args:
        T_a_b: (4, 4) transform from frame b to frame a.
        normals_b: (K, 3) unit normals in frame b.
        offsets_b: (K,) offsets in frame b, metres.

    Returns:
        normals_a (K, 3) and offsets_a (K,): ``n_a = R n_b``, ``d_a = d_b - n_a . t``.
    """
    R, t = T_a_b[:3, :3], T_a_b[:3, 3]
    normals_a = normals_b @ R.T
    return normals_a, offsets_b - normals_a @ t


def plane_transform_jacobian(T_a_b: np.ndarray) -> np.ndarray:
    """(4, 4) Jacobian of ``(n_a, d_a)`` with respect to ``(n_b, d_b)`` under ``T_a_b``."""
    R, t = T_a_b[:3, :3], T_a_b[:3, 3]
    J = np.zeros((4, 4))
    J[:3, :3] = R
    J[3, :3] = -(t @ R)
    J[3, 3] = 1.0
    return J


def dihedral_angles(normals: np.ndarray) -> np.ndarray:
    """(K, K) angles (rad, in [0, pi]) between every pair of oriented normals (K, 3).

    With normals oriented towards the sensor the angle between two planes' normals is
    invariant under rigid motion of the sensor, which is what the relative constraints
    of data association compare.
    """
    # np.clip's arithmetic (NaN kept) without its dispatch through two Python wrappers
    return np.arccos(np.minimum(np.maximum(normals @ normals.T, -1.0), 1.0))


def rotation_frames(n1: np.ndarray, n2: np.ndarray) -> np.ndarray:
    """The paper's frames ``U = [n1 n2 n1 x n2]``, orthonormalised: (M, 3) and (M, 3) normals
    to (M, 3, 3) frames with columns ``u1 = n1``, ``u3 = (n1 x n2) / |n1 x n2|``,
    ``u2 = u3 x u1`` (the part of n2 orthogonal to n1; equal to the paper's U when n1 is
    orthogonal to n2). Frames of (nearly) parallel pairs contain NaN.
    """
    c = cross_rows(n1, n2)
    s = np.sqrt(np.einsum("ij,ij->i", c, c))[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        u3 = np.where(s > 1e-9, c / s, np.nan)
    u1 = n1 / np.sqrt(np.einsum("ij,ij->i", n1, n1))[:, None]
    return np.stack([u1, cross_rows(u3, u1), u3], axis=2)


@numba.njit(cache=True)
def rotation_frame_into(n1, n2, U):  # pragma: no cover - compiled
    """:func:`rotation_frames` of one pair of normals (3,), (3,), written into ``U`` (3, 3),
    for compiled callers (the same arithmetic, one pair)."""
    c0 = n1[1] * n2[2] - n1[2] * n2[1]
    c1 = n1[2] * n2[0] - n1[0] * n2[2]
    c2 = n1[0] * n2[1] - n1[1] * n2[0]
    s = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if s > 1e-9:
        u3 = (c0 / s, c1 / s, c2 / s)
    else:
        u3 = (np.nan, np.nan, np.nan)
    r = np.sqrt(n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2])
    u1 = (n1[0] / r, n1[1] / r, n1[2] / r)
    U[0, 0], U[1, 0], U[2, 0] = u1
    U[0, 1] = u3[1] * u1[2] - u3[2] * u1[1]
    U[1, 1] = u3[2] * u1[0] - u3[0] * u1[2]
    U[2, 1] = u3[0] * u1[1] - u3[1] * u1[0]
    U[0, 2], U[1, 2], U[2, 2] = u3


def horizontal_reference_points(
    n1: np.ndarray, d1: np.ndarray, n2: np.ndarray, d2: np.ndarray, min_verticality: float = 0.2
) -> np.ndarray:
    """The paper's 2D reference point of plane pairs, vectorised.

    The intersection line of each pair is cut with the horizontal plane ``z = 0`` of the
    frame the planes are given in; the (x, y) of that point is the reference point. If the
    frame translates by ``t = (tx, ty, 0)`` the point moves by exactly ``-(tx, ty)`` (paper
    eq. 2); a vertical translation ``tz`` shifts it by ``tz * v_xy / v_z`` (v the line's
    direction), which vanishes for vertical lines: the 5-DoF model leaves z unobserved.

    Args:
        n1, n2: (M, 3) unit normals. d1, d2: (M,) offsets, metres.
        min_verticality: minimum ``|v_z|`` of the unit line direction; flatter lines give NaN.

    Returns:
        (M, 2) float64 reference points, metres; NaN rows for parallel or flat pairs.
    """
    n1 = np.atleast_2d(n1)
    n2 = np.atleast_2d(n2)
    v = cross_rows(n1, n2)
    norm_v = np.sqrt(np.einsum("ij,ij->i", v, v))
    with np.errstate(invalid="ignore", divide="ignore"):
        vz = np.abs(v[:, 2]) / norm_v
    ok = (norm_v > 1e-9) & (vz >= min_verticality)
    # Solve [n1; n2; e_z] p = [-d1; -d2; 0] for the xy part by Cramer's rule on the 2x2 block.
    a, b = n1[:, 0], n1[:, 1]
    c, e = n2[:, 0], n2[:, 1]
    det = a * e - b * c
    with np.errstate(invalid="ignore", divide="ignore"):
        x = (-np.asarray(d1) * e + np.asarray(d2) * b) / det
        y = (-a * np.asarray(d2) + c * np.asarray(d1)) / det
    out = np.column_stack([x, y])
    out[~ok] = np.nan
    return out


# --------------------------------------------------------------------------- gtsam


def plane_tangent_covariance(plane: Plane) -> np.ndarray:
    """(3, 3) covariance of ``plane`` in ``gtsam.OrientedPlane3``'s tangent coordinates.

    gtsam perturbs a plane by ``(Unit3 basis coefficients (2), d (1))``; the (4, 4) fit
    covariance of ``(n, d)`` is projected onto that basis. Raises when it is unknown.
    """
    import gtsam

    if plane.covariance is None:
        raise GeometryError("plane has no covariance")
    B = np.asarray(gtsam.Unit3(plane.normal).basis())  # (3, 2)
    P = np.zeros((4, 3))
    P[:3, :2] = B
    P[3, 2] = 1.0
    return P.T @ plane.covariance @ P
