"""The oracle: what any plane-landmark odometry could reach on simulated data.

It uses what only a simulation knows: every point's true surface (``Scan.label``) and the
true motion. Per epoch and surface, the labelled points are brought to the epoch's
reference time with the true poses (``p_ref = inv(T_world_base(t_k)) T_world_base(t_k +
t) p``: the true motion removed, i.e. deskewed exactly) and summarised by their count N,
centroid c and scatter S (:class:`SurfaceMoments`); a surface is a plane of the epoch
when it has at least ``min_points`` points spread over at least ``min_width_m`` across
(as the extraction's plane tests). Associations are known (the labels). The relative
pose ``T_prev_curr`` of two epochs minimises the sum of squared point-to-plane distances
of each epoch's points to the other epoch's TLS planes over all common planes,

    sum_s  n_p^T R S_c R^T n_p + N_c (n_p . (R c_c + t) + d_p)^2          (curr -> prev)
         + n_c^T R^T S_p R n_c + N_p (n_c . R^T (c_p - t) + d_c)^2        (prev -> curr)

i.e. weighted least squares over the planes with each plane's information (its points'
moments), solved by Gauss-Newton in 6 DoF from the constant-velocity prediction. With
noise-free points every term vanishes at the truth, so the oracle is exact at sigma = 0;
with noise its error is zero-mean to first order. Directions without enough information
(z without a horizontal plane, a corridor's length) keep the prediction and set the
status: "ok" (the 5 DoF roll, pitch, yaw, x, y all measured), "degenerate" (rotation
only) or "unresolved" (bridged by constant velocity). What is measured is judged on the
surfaces' true normals (a fitted normal's noise makes a corridor's length look measured)
from the 1-sigma errors the information implies at a reference noise of
``STATUS_SIGMA_M``: a property of the geometry, not of the noise level. The limits are
strict (0.05 deg, 2.5 cm at 2 cm noise): with looser ones a floor tilted by the
vehicle's pitch made a corridor's length "measured" and the estimate followed the noise
metres along it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.scan import Scan

#: Range noise (m) at which the status thresholds are evaluated.
STATUS_SIGMA_M = 0.02
#: 1-sigma limits of a measured rotation (deg, each axis) and xy translation (m, each axis).
MAX_ROTATION_SIGMA_DEG, MAX_XY_SIGMA_M = 0.05, 0.025


@dataclass(frozen=True, eq=False)
class SurfaceMoments:
    """The planes of one epoch, one per true surface seen as a plane.

    Attributes:
        ids: (K,) surface ids. count: (K,) points. centroid: (K, 3) m. scatter: (K, 3, 3)
        m^2, centred sums of outer products. normal: (K, 3) TLS unit normals. offset: (K,)
        m, ``n . p + d = 0``. All in the base frame at the epoch's reference time.
    """

    ids: np.ndarray
    count: np.ndarray
    centroid: np.ndarray
    scatter: np.ndarray
    normal: np.ndarray
    offset: np.ndarray
    true_normal: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.ids)

    def subset(self, idx: np.ndarray) -> SurfaceMoments:
        """The planes at ``idx`` (K',)."""
        truth = None if self.true_normal is None else self.true_normal[idx]
        return SurfaceMoments(
            self.ids[idx], self.count[idx], self.centroid[idx], self.scatter[idx],
            self.normal[idx], self.offset[idx], truth,
        )  # fmt: skip

    def judged(self) -> SurfaceMoments:
        """These planes with their true normals (when known) in place of the fitted ones:
        what the information is judged on (a fitted normal's noise would make a corridor's
        length look measured)."""
        if self.true_normal is None:
            return self
        sign = np.sign(np.einsum("ki,ki->k", self.true_normal, self.normal))[:, None]
        n = self.true_normal * np.where(sign == 0, 1.0, sign)
        d = -np.einsum("ki,ki->k", n, self.centroid)
        return SurfaceMoments(self.ids, self.count, self.centroid, self.scatter, n, d)


def deskewed_points(scan: Scan, trajectory, t_k: float) -> np.ndarray:
    """The scan's points (N, 3) in the base frame at ``t_k`` (s), moved with the true poses
    ``trajectory.poses`` from their own times ``t_k + scan.t`` (no ``t``: as given)."""
    if scan.t is None or len(scan) == 0 or not np.any(scan.t):
        return scan.points.copy()
    times, inverse = np.unique(scan.t, return_inverse=True)
    T = invert_transform(trajectory.pose(t_k))[None] @ trajectory.poses(t_k + times)
    R, p = T[inverse, :3, :3], T[inverse, :3, 3]
    return np.einsum("nij,nj->ni", R, scan.points) + p


def surface_moments(
    points: np.ndarray, labels: np.ndarray, min_points: int = 20, min_width_m: float = 0.2
) -> SurfaceMoments:
    """Per label >= 0 with at least ``min_points`` points (N, 3) whose in-plane minor
    extent ``2 sqrt(lambda_2 / N)`` is at least ``min_width_m``: moments and TLS plane."""
    lab = np.asarray(labels)
    ids, inverse, counts = np.unique(lab, return_inverse=True, return_counts=True)
    keep = []
    for j in np.flatnonzero((ids >= 0) & (counts >= min_points)):
        P = points[inverse == j]
        c = P.mean(axis=0)
        S = (P - c).T @ (P - c)
        evals, evecs = np.linalg.eigh(S)
        if 2.0 * np.sqrt(max(evals[1], 0.0) / len(P)) >= min_width_m:
            keep.append((ids[j], len(P), c, S, evecs[:, 0], float(-evecs[:, 0] @ c)))
    if not keep:
        z = np.zeros((0, 3))
        return SurfaceMoments(np.zeros(0, int), np.zeros(0, int), z, np.zeros((0, 3, 3)), z,
                              np.zeros(0))  # fmt: skip
    cols = list(zip(*keep, strict=True))
    return SurfaceMoments(*(np.array(c) for c in cols))


def epoch_moments(scan: Scan, trajectory, t_k: float, scene=None, **kwargs) -> SurfaceMoments:
    """:func:`surface_moments` of the scan's points deskewed with the true motion; with
    the ``scene`` (a :class:`planodom.simulation.Scene`) also the surfaces' true normals
    in the base frame at ``t_k`` (:meth:`SurfaceMoments.judged`)."""
    if scan.label is None:
        raise ValueError("the oracle needs simulated scans with labels")
    m = surface_moments(deskewed_points(scan, trajectory, t_k), scan.label, **kwargs)
    if scene is None or len(m) == 0:
        return m
    R_world_base = trajectory.pose(t_k)[:3, :3]
    truth = np.array([scene.by_id(int(i)).normal for i in m.ids]) @ R_world_base
    return SurfaceMoments(m.ids, m.count, m.centroid, m.scatter, m.normal, m.offset, truth)


def _roots(S: np.ndarray) -> np.ndarray:
    """(K, 3, 3) ``L`` with ``L L^T = S`` for PSD scatters (K, 3, 3)."""
    w, V = np.linalg.eigh(S)
    return V * np.sqrt(np.clip(w, 0.0, None))[:, None, :]


def _residuals(T: np.ndarray, prev: SurfaceMoments, curr: SurfaceMoments, roots) -> np.ndarray:
    """The point-to-plane residuals (module docstring) of both directions, metres."""
    R, t = T[:3, :3], T[:3, 3]
    Lp, Lc = roots
    npr, ncr = prev.normal, curr.normal
    a = np.einsum("kji,kj->ki", Lc, npr @ R)  # L_c^T R^T n_p
    b = np.sqrt(curr.count) * (np.einsum("ki,ki->k", npr, curr.centroid @ R.T + t) + prev.offset)
    c = np.einsum("kji,kj->ki", Lp, ncr @ R.T)  # L_p^T R n_c
    e = np.sqrt(prev.count) * (np.einsum("ki,ki->k", ncr, (prev.centroid - t) @ R) + curr.offset)
    return np.concatenate([a.ravel(), b, c.ravel(), e])


@dataclass(frozen=True)
class OracleEstimate:
    """One relative pose: ``T_prev_curr`` (4, 4), status ("ok" | "degenerate" |
    "unresolved"), common planes, and which parameters (6,) bool (body twist order wx,
    wy, wz, x, y, z) the planes measure."""

    T_prev_curr: np.ndarray
    status: str
    n_common: int
    measured: np.ndarray


def relative_pose(
    prev: SurfaceMoments, curr: SurfaceMoments, T_init: np.ndarray | None = None,
    iterations: int = 30,
) -> OracleEstimate:  # fmt: skip
    """The oracle's ``T_prev_curr`` of two epochs from their common planes (module
    docstring), by Gauss-Newton from ``T_init`` (default identity); minimum-norm steps
    leave directions without enough information at ``T_init``."""
    T0 = np.eye(4) if T_init is None else np.asarray(T_init, dtype=np.float64)
    common, ip, ic = np.intersect1d(prev.ids, curr.ids, return_indices=True)
    if len(common) == 0:
        return OracleEstimate(T0, "unresolved", 0, np.zeros(6, dtype=bool))
    p, c = prev.subset(ip), curr.subset(ic)
    roots = (_roots(p.scatter), _roots(c.scatter))
    pj, cj = p.judged(), c.judged()

    def subspace(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _strong_subspace(_jacobian(T, pj, cj, roots, _residuals(T, pj, cj, roots)))

    def solve(basis: np.ndarray) -> np.ndarray:
        T = T0
        for _ in range(iterations):
            r0 = _residuals(T, p, c, roots)
            A = _jacobian(T, p, c, roots, r0) @ basis
            step = basis @ np.linalg.lstsq(A, -r0, rcond=None)[0]
            T = T @ se3_exp(step)
            if np.max(np.abs(step)) < 1e-12:
                break
        return T

    # What is measured depends on the rotation (a corridor's direction in the current
    # frame): judged at the start, solved, judged again at that solution, solved again.
    basis, measured = subspace(T0)
    basis, measured = subspace(solve(basis))
    T = solve(basis)
    rot_ok, xy_ok = bool(measured[:3].all()), bool(measured[3:5].all())
    status = "ok" if rot_ok and xy_ok else "degenerate" if rot_ok else "unresolved"
    return OracleEstimate(T if status != "unresolved" else T0, status, len(common), measured)


#: Units of the parameters when judging what the information measures (rad, rad, rad, m, m, m).
_UNITS = (
    np.deg2rad(MAX_ROTATION_SIGMA_DEG) * np.r_[1.0, 1.0, 1.0, 0.0, 0.0, 0.0]
    + np.r_[0.0, 0.0, 0.0, 1.0, 1.0, 1.0] * MAX_XY_SIGMA_M
)


def _strong_subspace(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The directions (6, m) of the parameters the residuals measure, and which parameters
    (6,) bool are measured. In units of the status limits (``_UNITS``), the information
    at ``STATUS_SIGMA_M`` has eigen-directions with eigenvalue >= 1 (1-sigma error within
    the limit: strong) or below (weak); Gauss-Newton steps stay in the strong ones (so a
    corridor's length keeps the prediction instead of following the noise), and a
    parameter is measured when at most 10 % of it lies in the weak ones."""
    D = np.diag(_UNITS)
    H = D @ (J.T @ J) @ D / STATUS_SIGMA_M**2
    w, V = np.linalg.eigh(H)
    strong = w >= 1.0
    measured = np.linalg.norm(V[:, ~strong], axis=1) <= 0.1
    return D @ V[:, strong], measured


def _jacobian(T, p, c, roots, r0, h: float = 1e-7) -> np.ndarray:
    """Forward-difference Jacobian (M, 6) of the residuals in the right perturbation."""
    steps = _STEPS if h == _H else [se3_exp(h * e) for e in np.eye(6)]
    cols = [(_residuals(T @ step, p, c, roots) - r0) / h for step in steps]
    return np.column_stack(cols)


#: The forward difference's step and its six perturbations ``se3_exp(h e_i)`` (4, 4),
#: computed once (the same matrices each call: they were a third of the oracle's CPU).
_H = 1e-7
_STEPS = [se3_exp(_H * e) for e in np.eye(6)]


@dataclass(frozen=True, eq=False)
class OracleRun:
    """The oracle over a run: ``poses`` (E, 4, 4) chained from identity, ``statuses``
    ("first", then per epoch), ``n_planes`` (E,) surfaces seen as planes, ``n_common``
    (E,) planes shared with the previous epoch."""

    poses: np.ndarray
    statuses: list[str]
    n_planes: np.ndarray
    n_common: np.ndarray

    @property
    def n_unresolved(self) -> int:
        return sum(s == "unresolved" for s in self.statuses)

    @property
    def n_degenerate(self) -> int:
        return sum(s == "degenerate" for s in self.statuses)


def run_oracle(
    scans: Sequence[Scan], times: np.ndarray, trajectory, scene=None, min_points: int = 20,
    min_width_m: float = 0.2,
) -> OracleRun:  # fmt: skip
    """The oracle over consecutive epochs of a simulated run (``scans`` with labels and,
    for continuous motion, times; ``times`` (E,) reference times, s; ``trajectory`` the
    true ``T_world_base(t)``; ``scene`` its surfaces, to judge what the planes measure on
    their true normals); unresolved epochs are bridged by constant velocity."""
    kw = {"scene": scene, "min_points": min_points, "min_width_m": min_width_m}
    pairs = zip(scans, times, strict=True)
    moments = [epoch_moments(s, trajectory, float(t), **kw) for s, t in pairs]
    poses, statuses, common = [np.eye(4)], ["first"], [0]
    velocity = np.zeros(6)  # twist per second of the last estimate
    for k in range(1, len(scans)):
        dt = float(times[k] - times[k - 1])
        est = relative_pose(moments[k - 1], moments[k], se3_exp(velocity * dt))
        if est.status != "unresolved" and dt > 0:
            velocity = se3_log(est.T_prev_curr) / dt
        poses.append(poses[-1] @ est.T_prev_curr)
        statuses.append(est.status)
        common.append(est.n_common)
    n_planes = np.array([len(m) for m in moments])
    return OracleRun(np.array(poses), statuses, n_planes, np.array(common))
