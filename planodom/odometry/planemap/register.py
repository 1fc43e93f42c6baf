"""Association of a scan's planes with the map, and the robust Gauss-Newton on moments.

Gates (KISS-ICP's adaptive threshold, per plane). ``s_rot, s_t`` are the RMS of the
constant-velocity model's deviations so far (``|log(inv(T_pred) T_est)|``): no hand-set
speed. A scan plane may associate with a landmark when, under the pose being refined, the
moved normal is within ``3 sqrt(s_rot^2 + var_n + var_n_landmark)``, the RMS distance of
its points to the landmark plane (from the moments: ``e^2 = (n.(R c + t) + d)^2 + n^T R S
R^T n / N``) within ``3 sqrt((s_t + s_rot |c|)^2 + var_offsets + sigma^2 + bias^2)``, and
the supports (bounding circles) come within that distance. The landmark with the least
``e^2`` wins (``planemap.tie_rule: distance``; the other rules in :func:`tie_cost`);
several planes may share one. Association and Gauss-Newton alternate (ICP's
outer loop) with the gates fixed per scan.

Gauss-Newton: the four moment residuals per association (:mod:`.moments`), each whitened
by its variance (plane noise with the laser bias, plus the landmark's own uncertainty at
the moved centroid / along the moved axes) times the scan's robust residual scale
(:func:`residual_scale`, at least 1: the variances honest when the whole scan disagrees
more than its model says), Cauchy weights on the whitened chi of the
offset and the two tilt residuals (the thickness residual is the plane's own noise and
carries no pose information to first order: it stays in the sum, not in the kernel);
the associations that end as outliers (weight at most 0.5) are then dropped and the rest
solved again (:func:`solve`).
The step is solved on the eigenvalues of the (length-scaled) information: a direction with
no information keeps its value (the prediction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.config import PlanemapConfig
from planodom.median import median
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.moments import Moments, residual_variance
from planodom.odometry.planemap.outliers import (
    deleted_chi2,
    pose_deviation,
    residual_scale,
    whitened,
)
from planodom.odometry.planemap.register_kernels import (
    nearest_gated_kernel,
    normal_equations_kernel,
    whitened_kernel,
)
from planodom.rotvec import rotation_matrices


@dataclass(frozen=True, eq=False)
class ScanPlanes:
    """A scan's planes as the registration needs them (scan frame).

    Attributes:
        m: their moments. normals: (K, 3) oriented normals.
        var_n: (K,) normal variance per axis (rad^2), var_o: (K,) offset variance at the
            centroid (m^2), laser bias included. lam, E: eigen-decomposition of the
            scatters (ascending). sigma: point noise (m). s2: (K,) residual variances.
            bias: the laser bias (m) they were computed with. deskew: (K, 4) the
            variance each moment residual gains from the deskewing twist's error
            (``planemap.deskew_variance``, :func:`deskew_variances`), or None.
        time_moments: (K, 5, 4, 4) the planes' time moments (``PlaneSupport.
            time_moments``) for the continuous-time registration (:mod:`.ctreg`), or None.
        led_var: (6,) the led twist's error variance (``lead_weights: unknown``), or None.
    """

    m: Moments
    normals: np.ndarray
    var_n: np.ndarray
    var_o: np.ndarray
    lam: np.ndarray
    E: np.ndarray
    sigma: float
    s2: np.ndarray
    bias: float = 0.0
    deskew: np.ndarray | None = None
    time_moments: np.ndarray | None = None
    led_var: np.ndarray | None = None

    @classmethod
    def of(
        cls,
        m: Moments,
        normals: np.ndarray,
        sigma: float,
        bias: float,
        deskew_cov: np.ndarray | None = None,
    ) -> ScanPlanes:
        """The registration inputs of planes with moments ``m``; ``deskew_cov`` (K, 4, 4):
        the covariance of each plane's ``(n, d)`` from the deskewing twist's error."""
        lam, E = np.linalg.eigh(m.S)
        rows = np.maximum(m.rows, 1.0)
        var_n = (sigma**2 + bias**2 * m.N / rows) / np.maximum(lam[:, 1], 1e-12)
        var_o = sigma**2 / np.maximum(m.N, 1.0) + bias**2 / rows
        s2 = residual_variance(sigma, bias, m.N, m.rows)
        deskew = None if deskew_cov is None else deskew_variances(m, lam, E, deskew_cov)
        return cls(m, normals, var_n, var_o, lam, E, sigma, s2, bias, deskew)

    def variances(self, jj: np.ndarray) -> np.ndarray:
        """The plane noise of the moment residuals of planes ``jj`` (m,): (m,) alike for
        all four, or (m, 4) with the deskewing error."""
        return self.s2[jj] if self.deskew is None else self.s2[jj][:, None] + self.deskew[jj]

    def __len__(self) -> int:
        return len(self.m)


def deskew_variances(m: Moments, lam: np.ndarray, E: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(K, 4) variance of each moment residual (offset, then along e_0 (the normal), e_1,
    e_2) from a covariance ``cov`` (K, 4, 4) of the planes' ``(n, d)``: the points' mean
    offset at the centroid ``-(c . dn + dd)`` times ``sqrt(N)``, and ``sqrt(lam_k) e_k .
    dn`` (the scatter's axes turn with the normal)."""
    cd = np.concatenate([m.c, np.ones((len(m), 1))], axis=1)
    out = np.empty((len(m), 4))
    out[:, 0] = m.N * np.einsum("ki,kij,kj->k", cd, cov, cd)
    out[:, 1:] = lam * np.einsum("kai,kab,kbi->ki", E, cov[:, :3, :3], E)
    return out


@dataclass(frozen=True, eq=False)
class Registration:
    """A pose of the scan against the map and how well it is supported.

    Attributes:
        T: (4, 4) world from scan. H: (6, 6) information of (rotation, translation) in
            the perturbation ``R <- exp(w) R, t <- t + dt``.
        landmarks, planes: (m,) associated landmark and scan plane indices.
        weights: (m,) Cauchy weights. stage: which hypothesis it started from.
    """

    T: np.ndarray
    H: np.ndarray
    landmarks: np.ndarray
    planes: np.ndarray
    weights: np.ndarray
    stage: str

    @property
    def inliers(self) -> np.ndarray:
        """Scan plane indices of the inlier associations (weight above 0.5)."""
        return self.planes[self.weights > 0.5]


def plane_landmark_errors(
    M: PlaneMap, T: np.ndarray, cur: ScanPlanes
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per (plane, landmark) under pose ``T``: normal angle (K, L) rad, mean squared
    point distance ``e^2`` (K, L) m^2, and the support separation (K, L) m."""
    R, t = T[:3, :3], T[:3, 3]
    nw = cur.normals @ R.T
    cw = cur.m.c @ R.T + t
    ang = np.arccos(np.clip(nw @ M.n.T, -1.0, 1.0))
    off = cw @ M.n.T + M.d[None]
    Sw = R @ cur.m.S @ R.T
    nn = (M.n[:, :, None] * M.n[:, None, :]).reshape(-1, 9)  # n n^T per landmark
    e2 = off**2 + (Sw.reshape(-1, 9) @ nn.T) / cur.m.N[:, None]
    radius = np.sqrt(3.0 * np.trace(cur.m.S, axis1=1, axis2=2) / cur.m.N)
    sep = np.linalg.norm(cw[:, None] - M.c[None], axis=2) - M.radius[None] - radius[:, None]
    return ang, e2, sep


@dataclass(frozen=True, eq=False)
class Candidates:
    """Every (scan plane, landmark) pair under one pose and the gates (module docstring).

    Attributes:
        ok: (K, L) the pair passes the normal, distance and support gates.
        ang: (K, L) angle between the moved normal and the landmark's (rad).
        e2: (K, L) mean squared distance of the plane's points to the landmark (m^2).
        var_ang: (K, L) variance per axis of that angle (rad^2): the gate's over 9.
        var_d: (K, L) variance of the distance (m^2): the gate's over 9 (pose, scan
            plane, the landmark's offset at the moved centroid, point noise and bias).
        var_landmark: (K, L) the landmark's offset variance at the moved centroid (m^2).
        var_pose: (K, 1) the prediction's offset variance at the plane (m^2): ``(s_t +
            s_r lever)^2``.
    """

    ok: np.ndarray
    ang: np.ndarray
    e2: np.ndarray
    var_ang: np.ndarray
    var_d: np.ndarray
    var_landmark: np.ndarray
    var_pose: np.ndarray


def candidates(
    M: PlaneMap, T: np.ndarray, cur: ScanPlanes, s_r: float, s_t: float, bias: float
) -> Candidates:
    """The gated pairs of the scan's planes and the map's landmarks under pose ``T``
    (world from scan), with the gates' RMS deviations ``s_r`` (rad) and ``s_t`` (m) and
    the laser bias ``bias`` (m); the map must not be empty."""
    ang, e2, sep = plane_landmark_errors(M, T, cur)
    var_nL = np.trace(M.cov_n, axis1=1, axis2=2) / 2
    var_ang = s_r**2 + cur.var_n[:, None] + var_nL[None]
    g_ang = 3 * np.sqrt(var_ang)
    cw = cur.m.c @ T[:3, :3].T + T[:3, 3]
    # (x - c)^T C (x - c) for every plane centroid x and landmark (c, C), as matrix products.
    C = M.cov_n
    Cc = np.einsum("lik,lk->li", C, M.c)
    xx = (cw[:, :, None] * cw[:, None, :]).reshape(-1, 9)
    quad = xx @ C.reshape(-1, 9).T - 2.0 * cw @ Cc.T + np.einsum("li,li->l", M.c, Cc)[None]
    vL = quad + M.var_o[None]
    radius = np.sqrt(3.0 * np.trace(cur.m.S, axis1=1, axis2=2) / cur.m.N)
    lever = np.linalg.norm(cur.m.c, axis=1) + radius
    v_pose = (s_t + s_r * lever[:, None]) ** 2
    g_d2 = 9 * (v_pose + cur.var_o[:, None] + vL + cur.sigma**2 + bias**2)
    ok = (ang <= g_ang) & (e2 <= g_d2) & (sep <= np.sqrt(g_d2))
    return Candidates(ok, ang, e2, var_ang, g_d2 / 9, vL, v_pose)


def tie_cost(c: Candidates, rule: str) -> np.ndarray:
    """(K, L) the cost by which a scan plane chooses among its gated landmarks (the least
    wins; inf: not gated; ``PlanemapConfig.tie_rule``). ``distance``: the mean squared
    distance ``e^2``. ``likelihood``: minus twice the Gaussian log-likelihood of the
    pair's distance and normal angle under the gates' variances, ``e^2 / var_d + log
    var_d + ang^2 / var_ang + 2 log var_ang`` (two normal axes): a landmark whose own
    uncertainty at the plane is large (a few points fading far away, extrapolated)
    explains any distance, so its whitened distance is small, but its density is low.
    ``informative``: ``e^2``, but a landmark that knows the plane's offset less well
    than the prediction does (its offset variance at the plane above the prediction's,
    ``var_landmark > var_pose``) only among the plane's candidates when no other is
    informative (:func:`associate`): it could not correct the pose there, only drag it."""
    if rule == "likelihood":
        cost = c.e2 / c.var_d + np.log(c.var_d) + c.ang**2 / c.var_ang + 2.0 * np.log(c.var_ang)
        return np.where(c.ok, cost, np.inf)
    if rule == "informative":
        useful = c.ok & (c.var_landmark <= c.var_pose)
        use = np.where(useful.any(axis=1, keepdims=True), useful, c.ok)
        return np.where(use, c.e2, np.inf)
    return np.where(c.ok, c.e2, np.inf)


def associate(
    M: PlaneMap,
    T: np.ndarray,
    cur: ScanPlanes,
    s_r: float,
    s_t: float,
    bias: float,
    rule: str = "distance",
) -> np.ndarray:
    """(K,) the best landmark of every scan plane under pose ``T`` (-1: none), the tie
    between gated landmarks broken by ``rule`` (:func:`tie_cost`)."""
    if len(M) == 0 or len(cur) == 0:
        return np.full(len(cur), -1)
    if rule == "distance" and len(M) > 1 and len(cur) > 1:
        # compiled, the same arithmetic (numpy's products with one plane or landmark are
        # matrix-vector ones, summed otherwise: those few take the numpy path)
        R = np.ascontiguousarray(T[:3, :3])
        ang = np.arccos(np.clip(cur.normals @ R.T @ M.n.T, -1.0, 1.0))
        return nearest_gated_kernel(
            ang, R, T[:3, 3].copy(), cur.m.c, cur.m.S, cur.m.N, cur.var_n, cur.var_o,
            float(cur.sigma), M.d, M.c, M.radius, M.cov_n, M.var_o, M.n,
            float(s_r), float(s_t), float(bias),
        )  # fmt: skip
    cost = tie_cost(candidates(M, T, cur, s_r, s_t, bias), rule)
    best = np.argmin(cost, axis=1)
    has = np.isfinite(cost[np.arange(len(cur)), best])
    return np.where(has, best, -1)


def solve(
    M: PlaneMap,
    T0: np.ndarray,
    cur: ScanPlanes,
    lm: np.ndarray,
    jj: np.ndarray,
    config: PlanemapConfig,
    prior: tuple[np.ndarray, float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robust Gauss-Newton of the associations (scan plane ``jj[k]`` -> landmark
    ``lm[k]``) from ``T0``: the pose, its information (6, 6) and the weights (m,).

    With ``config.outliers`` ``dropped`` (``PlanemapConfig.outliers``), the associations
    it ends with a Cauchy weight of at most 0.5 (outliers: whitened residuals, in units
    of the scan's residual scale, beyond twice the kernel scale; what
    :attr:`Registration.inliers` and the map update leave out) are dropped and the rest
    solved again, until the set repeats (at most ``association_rounds``); the dropped
    ones get weight 0. The Cauchy kernel alone lets every outlier keep a pull of ``c^2 /
    chi`` (as much as an inlier at chi ~ 1 for chi ~ 4 c): on a parked lidar a handful
    of wrong associations (fragments of curved surfaces at a few metres, matched through
    the wide gates of their poorly defined normals) moved it 5-24 cm along the one
    direction only they observe, at 7 of the information's sigmas; and the information
    (the covariance reported) must be that of the associations the pose rests on.
    Without the residual scale the same rule dropped the walls of a hand-held corridor
    walk (5 cm off at 0.5 cm model sigmas, all of them) and left it degenerate; with it
    that walk is as before or better. ``doubtful``: the same, but only associations whose
    scan plane's normal sigma exceeds ``config.doubtful_normal_deg`` can be dropped.
    ``deleted``: :func:`_drop_deleted` (the leave-one-out test of :mod:`.outliers`
    against the other associations and the prediction ``prior = (T_pred, s_rot, s_t)``;
    without a prior, an uninformative one about ``T0``)."""
    T, H, w = _gauss_newton(M, T0, cur, lm, jj, config)
    if config.outliers == "kernel":
        return T, H, w
    if config.outliers == "deleted":
        return _drop_deleted(M, T, H, w, cur, lm, jj, config, prior or (T0, np.pi, 1e3))
    # ``doubtful``: only an association whose scan plane has an ill-defined normal can be
    # wrong (the others are the surface they match; an excess residual is model error)
    certain = np.zeros(len(lm), dtype=bool)
    if config.outliers == "doubtful":
        certain = np.sqrt(cur.var_n[jj]) <= np.radians(config.doubtful_normal_deg)
    keep = (w > 0.5) | certain
    for _ in range(config.association_rounds):
        if keep.all() or np.count_nonzero(keep) < 3:
            break
        T, H, w_kept = _gauss_newton(M, T, cur, lm[keep], jj[keep], config)
        w = np.zeros(len(lm))
        w[keep] = w_kept
        new = (w > 0.5) | (certain & keep)
        if np.array_equal(new, keep):
            break
        keep = new
    return T, H, w


def _drop_deleted(
    M: PlaneMap,
    T: np.ndarray,
    H: np.ndarray,
    w: np.ndarray,
    cur: ScanPlanes,
    lm: np.ndarray,
    jj: np.ndarray,
    config: PlanemapConfig,
    prior: tuple[np.ndarray, float, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``outliers: deleted`` (:mod:`.outliers`): while the association with the largest
    deleted chi-square (its residual under the pose of the others and the prediction
    ``prior = (T_pred, s_rot, s_t)``) is an outlier by the kernel's own definition (the
    Cauchy weight it would get at most 0.5: mean squared whitened residual at least
    ``c^2``), drop it and solve again; one at a time, as data snooping does, so that a
    gross outlier does not make its neighbours look bad (swamping). Dropped ones get
    weight 0."""
    T_pred, s_r, s_t = prior
    # the deviations are RMS of 3D vectors: per axis their variance is a third
    info = np.r_[np.full(3, 3.0 / max(s_r, 1e-9) ** 2), np.full(3, 3.0 / max(s_t, 1e-9) ** 2)]
    keep = np.ones(len(lm), dtype=bool)
    limit = 3.0 * config.cauchy_scale**2
    while np.count_nonzero(keep) > 3:
        idx = np.flatnonzero(keep)
        N, c, lam, E = cur.m.N[jj[idx]], cur.m.c[jj[idx]], cur.lam[jj[idx]], cur.E[jj[idx]]
        r, J, v, chi2 = whitened(
            M, T[:3, :3], T[:3, 3], N, c, lam, E, cur.variances(jj[idx]), lm[idx]
        )
        k2 = residual_scale(chi2)
        wk = 1.0 / (1.0 + chi2 / (k2 * config.cauchy_scale**2))
        stat = deleted_chi2(r, J, k2 * v, wk, pose_deviation(T, T_pred), info)
        worst = int(np.argmax(stat))
        if stat[worst] < limit:
            break
        keep[idx[worst]] = False
        T, H, w_kept = _gauss_newton(M, T, cur, lm[keep], jj[keep], config)
        w = np.zeros(len(lm))
        w[keep] = w_kept
    return T, H, w


def newton_step(H: np.ndarray, g: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """The Gauss-Newton step ``-H^+ g`` (n,) of the normal equations ``H`` (n, n) and
    gradient ``g`` (n,), solved on ``H`` scaled by ``scale`` (n,) (Jacobi) with the
    pseudo-inverse's eigenvalues below 1e-9 of the largest dropped (an unobserved
    direction does not move)."""
    ev, V = np.linalg.eigh(H / np.outer(scale, scale))
    inv = np.where(ev > 1e-9 * ev.max(), 1.0 / np.maximum(ev, 1e-300), 0.0)
    return -((V * inv) @ V.T @ (g / scale)) / scale


def _gauss_newton(
    M: PlaneMap,
    T0: np.ndarray,
    cur: ScanPlanes,
    lm: np.ndarray,
    jj: np.ndarray,
    config: PlanemapConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cauchy-weighted Gauss-Newton of all the associations given (see :func:`solve`)."""
    R, t = T0[:3, :3].copy(), T0[:3, 3].copy()
    N, c, lam, E = cur.m.N[jj], cur.m.c[jj], cur.lam[jj], cur.E[jj]
    s2 = cur.variances(jj)
    s2 = np.ascontiguousarray(np.broadcast_to(s2[:, None], (len(jj), 4)) if s2.ndim == 1 else s2)
    n_l, d_l, cov_l, c_l, vo_l = M.n[lm], M.d[lm], M.cov_n[lm], M.c[lm], M.var_o[lm]
    H, w = np.eye(6), np.ones(len(lm))
    # Length scale of the solve: rotation and translation steps of comparable size.
    L = max(median(np.linalg.norm(c, axis=1)), 1.0)
    scale = np.r_[np.ones(3), np.full(3, 1.0 / L)]
    for _ in range(config.gn_iterations):
        # :func:`.outliers.whitened` and the weighted normal equations (:mod:`.register_kernels`)
        r, J, v, chi2 = whitened_kernel(R, t, c @ R.T, n_l, d_l, cov_l, c_l, vo_l, N, lam, E, s2)
        k2 = residual_scale(chi2)
        w, H, g = normal_equations_kernel(r, J, v, chi2, k2, config.cauchy_scale**2)
        dx = newton_step(H, g, scale)
        R = rotation_matrices(dx[:3]) @ R
        t = t + dx[3:]
        if np.linalg.norm(dx[:3]) < 1e-9 and np.linalg.norm(dx[3:]) < 1e-8:
            break
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T, H, w


def register(
    M: PlaneMap,
    T0: np.ndarray,
    cur: ScanPlanes,
    s_r: float,
    s_t: float,
    config: PlanemapConfig,
    stage: str,
) -> Registration:
    """Association and Gauss-Newton alternated from ``T0`` until the associations repeat
    (at most ``association_rounds``)."""
    T, H = T0, np.zeros((6, 6))
    w = np.zeros(0)
    lm = jj = np.zeros(0, dtype=np.intp)
    seen = None
    for _ in range(config.association_rounds):
        a = associate(M, T, cur, s_r, s_t, cur.bias, config.tie_rule)
        key = a.tobytes()
        if key == seen:
            break
        seen = key
        jj_new = np.flatnonzero(a >= 0)
        if len(jj_new) < 3:
            if len(jj) == 0:
                lm, jj = a[jj_new], jj_new
            break
        jj, lm = jj_new, a[jj_new]
        T, H, w = solve(M, T, cur, lm, jj, config, (T0, s_r, s_t))
    if len(w) != len(jj):
        w = np.zeros(len(jj))
    return Registration(T, H, lm, jj, w, stage)


def score(M: PlaneMap, T: np.ndarray, cur: ScanPlanes, config: PlanemapConfig) -> float:
    """Robust point-to-plane cost of ALL the scan's planes against the map under ``T``
    (lower is better): per plane the least whitened cost over landmarks with a normal
    within 3 of its sigmas plus 3 deg, ``(N e^2 - lam_min) / s2`` (the plane's own
    thickness removed: about chi^2 with 3 DoF), truncated at 3 residuals of
    ``score_truncation`` sigmas; an unexplained plane costs the truncation."""
    cap = 3.0 * config.score_truncation**2
    if len(M) == 0 or len(cur) == 0:
        return cap * len(cur)
    ang, e2, _ = plane_landmark_errors(M, T, cur)
    lim = np.radians(3.0) + 3 * np.sqrt(cur.var_n)
    chi2 = (cur.m.N[:, None] * e2 - cur.lam[:, :1]) / cur.s2[:, None]
    chi2 = np.where(ang <= lim[:, None], np.maximum(chi2, 0.0), np.inf)
    return float(np.minimum(chi2.min(axis=1), cap).sum())
