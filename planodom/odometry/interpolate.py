"""Deskewing through the poses of the neighbouring epochs (a continuous-time motion model).

The streaming odometry deskews an epoch with one constant twist, predicted from the past
(:mod:`planodom.odometry.deskew`): on a drive whose rate of turn changes within an epoch it
leaves ~1e-3 deg per epoch even without noise. Once the poses of the epochs on both sides
are known (an odometry pass, or a smoother), each point can be brought to its epoch's
reference time by the motion interpolated through them instead:

    xi_j = log(T_k^-1 T_j)              j in the window of epochs around [t_k, t_k+1]
    xi(t) = sum_j L_j(t) xi_j            Lagrange polynomial through (t_j - t_k, xi_j)
    T_k_t = exp(xi(t)),  p_k = T_k_t p_t

with the window the ``order + 1`` epochs nearest the interval (``k - 1 .. k + 2`` for a
cubic, shifted at the ends of the run). The polynomial lives in the tangent space at
``T_k`` (a chart, exact at its nodes; a few degrees of rotation per window keep it far
from the log's singularity). Why not a library spline: scipy's ``RotationSpline`` covers
rotations only, and an SE(3) spline of gtsam or Sophus is not in their Python bindings;
the chart polynomial is a few lines of numpy on :func:`planodom.geometry.se3_log` /
:func:`planodom.geometry.se3_exp`. A cubic's error shrinks as the fourth power of the
epoch period: measured on the simulated paper loop at 10 Hz with the true poses, 5e-5 deg.

The interpolation follows the nodes' noise. With ``variances`` and a window of ``n_fit``
nodes wider than ``order + 1`` (``odometry.deskew_fit``), the curve is instead the
least-squares polynomial of the same degree over the window, each tangent component
weighted by the inverse of the node's variance (:func:`fit_weights`), or fitted to the
increments between the nodes, whose errors are independent where the chained poses' are a
random walk (:func:`increment_fit_weights`); both remain exact for a polynomial motion of
that degree. Why not a smoothing spline (``scipy.interpolate.make_smoothing_spline``) with
a white-noise-acceleration prior: at the vehicle's own rate of change of turn rate
(~0.1-0.3 rad/s per second) and the odometry's per-epoch sigmas (0.005-0.05 deg) its
equivalent kernel is narrower than one epoch, i.e. it interpolates.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planodom.errors import GeometryError
from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.scan import Scan


def window(k: int, n: int, order: int) -> np.ndarray:
    """Indices (order + 1,) of the epochs the motion of epoch ``k`` (of ``n``) is
    interpolated through: centred on the interval ``[k, k + 1]``, shifted to stay in
    ``[0, n)`` (fewer when ``n <= order``)."""
    m = min(order + 1, n)
    lo = k - (m - 1) // 2
    lo = min(max(lo, 0), n - m)
    return np.arange(lo, lo + m)


def lagrange_weights(nodes: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Lagrange basis ``L_j(t)`` (T, J) of the polynomial through ``nodes`` (J,) seconds
    (distinct), at ``t`` (T,) seconds."""
    nodes = np.asarray(nodes, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    out = np.ones((len(t), len(nodes)))
    for j, tj in enumerate(nodes):
        for i, ti in enumerate(nodes):
            if i != j:
                out[:, j] *= (t - ti) / (tj - ti)
    return out


def fit_weights(
    nodes: np.ndarray, t: np.ndarray, order: int, weights: np.ndarray | None = None
) -> np.ndarray:
    """The linear smoother ``H`` (T, J) of the weighted least-squares polynomial of degree
    ``order`` through the values at ``nodes`` (J,) s, evaluated at ``t`` (T,) s: the fit's
    values are ``H @ y``. ``weights`` (J,) >= 0 (default all 1; at least ``order + 1``
    positive). With ``J == order + 1`` nodes it is the interpolating polynomial
    (:func:`lagrange_weights`) whatever the weights; either way it reproduces a polynomial of
    degree <= ``order`` exactly."""
    nodes = np.asarray(nodes, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    w = np.ones(len(nodes)) if weights is None else np.asarray(weights, dtype=np.float64)
    if int(np.sum(w > 0)) < order + 1:
        raise GeometryError(f"{int(np.sum(w > 0))} weighted nodes for a degree {order} fit")
    scale = max(float(np.max(np.abs(nodes))), 1e-12)  # conditioning of the Vandermonde
    B = np.vander(nodes / scale, order + 1, increasing=True)  # (J, p+1)
    Bt = np.vander(t / scale, order + 1, increasing=True)  # (T, p+1)
    sw = np.sqrt(w)[:, None]
    # least squares of sqrt(W) B c = sqrt(W) y: c = pinv(sqrt(W) B) sqrt(W) y
    return Bt @ (np.linalg.pinv(sw * B) * sw.T)


def increment_fit_weights(
    nodes: np.ndarray, t: np.ndarray, order: int, weights: np.ndarray | None = None
) -> np.ndarray:
    """Like :func:`fit_weights`, but the polynomial's shape is fitted to the increments
    between consecutive nodes ``y[j + 1] - y[j]`` (weighted by ``2 / (1 / w_j + 1 / w_j+1)``,
    the inverse of their mean variance), and its constant to the nodes' mean. Why: the
    nodes are poses chained from the odometry's steps, so their errors are a random walk
    whose increments, not values, are independent; one wrong step shifts every later node,
    which a fit to the values spreads over the window. Exact for a polynomial of degree
    <= ``order``; with ``order + 1`` nodes the interpolating polynomial."""
    nodes = np.asarray(nodes, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    w = np.ones(len(nodes)) if weights is None else np.asarray(weights, dtype=np.float64)
    with np.errstate(divide="ignore"):
        wi = np.where((w[1:] > 0) & (w[:-1] > 0), 2.0 / (1.0 / w[1:] + 1.0 / w[:-1]), 0.0)
    if int(np.sum(wi > 0)) < order:
        raise GeometryError(f"{int(np.sum(wi > 0))} weighted increments for a degree {order} fit")
    scale = max(float(np.max(np.abs(nodes))), 1e-12)  # conditioning of the Vandermonde
    B = np.vander(nodes / scale, order + 1, increasing=True)[:, 1:]  # (J, p): no constant
    Bt = np.vander(t / scale, order + 1, increasing=True)[:, 1:]  # (T, p)
    D = np.diff(np.eye(len(nodes)), axis=0)  # (J-1, J): increments
    sw = np.sqrt(wi)[:, None]
    A = np.linalg.pinv(sw * (D @ B)) @ (sw * D)  # (p, J): shape coefficients from y
    mean = np.full((1, len(nodes)), 1.0 / len(nodes))
    return Bt @ A + mean - mean @ B @ A  # constant: the nodes' mean less the shape's


def curve_poses(
    node_times: np.ndarray,
    node_poses: np.ndarray,
    around: float,
    t: np.ndarray,
    order: int = 3,
    variances: np.ndarray | None = None,
    n_fit: int | None = None,
    increments: bool = False,
) -> np.ndarray:
    """``T_world_base`` (T, 4, 4) at the absolute times ``t`` (T,) s on the polynomial
    curve through the ``order + 1`` nodes nearest the time ``around`` (module docstring);
    with ``n_fit`` > ``order + 1`` and ``variances``, the weighted least-squares
    polynomial over the ``n_fit`` nearest nodes instead, each tangent component weighted
    by the inverse of the node's variance of it (infinite: not used).

    Args:
        node_times: (J,) seconds, strictly increasing. node_poses: (J, 4, 4).
        variances: (J, 6) of the nodes' tangent components (rotation rad^2, then
            translation m^2), or None (interpolation through ``order + 1`` nodes).
        n_fit: nodes in the fit's window (None or <= ``order + 1``: interpolation).
        increments: fit the shape to the nodes' increments (:func:`increment_fit_weights`).
    """
    node_times = np.asarray(node_times, dtype=np.float64)
    if len(node_times) != len(node_poses) or len(node_times) == 0:
        raise GeometryError(f"{len(node_times)} node times for {len(node_poses)} poses")
    if np.any(np.diff(node_times) <= 0):
        raise GeometryError("node times must increase strictly to interpolate between them")
    k = int(np.clip(np.searchsorted(node_times, around, side="right") - 1, 0, len(node_times) - 1))
    fit = variances is not None and n_fit is not None and n_fit > order + 1
    idx = window(k, len(node_times), (n_fit - 1) if fit and n_fit else order)
    anchor = node_poses[idx[len(idx) // 2]]
    xi = se3_log(invert_transform(anchor) @ node_poses[idx])  # (J, 6)
    tn, tt = node_times[idx] - around, np.asarray(t, np.float64) - around
    if not fit or variances is None or len(idx) <= order + 1:
        return anchor @ se3_exp(lagrange_weights(tn, tt) @ xi)
    w = _component_weights(np.asarray(variances, dtype=np.float64)[idx], order)
    smoother = increment_fit_weights if increments else fit_weights
    out = np.stack([smoother(tn, tt, order, w[:, c]) @ xi[:, c] for c in range(6)], axis=1)
    return anchor @ se3_exp(out)


def _component_weights(variances: np.ndarray, order: int) -> np.ndarray:
    """(J, 6) weights ``1 / variance`` of a window's nodes, each component normalised to a
    mean of 1 over its used nodes; a component with fewer than ``order + 1`` finite
    positive variances gets equal weights on the nodes with a finite one (or all)."""
    variances = variances.copy()
    for c in range(variances.shape[1]):  # a variance of 0: as the smallest positive one
        v = variances[:, c]
        positive = v[np.isfinite(v) & (v > 0)]
        v[v <= 0] = positive.min() if len(positive) else 1.0
    w = np.where(np.isfinite(variances), 1.0 / variances, 0.0)
    # no node's weight below 1 % of the window's median: a degenerate epoch's translation
    # variance (metres) would otherwise leave a cubic over a few nodes undetermined
    # (measured on a 5 Hz 2D rig at 2 cm: 22 of 60 epochs unresolved without the floor)
    for c in range(w.shape[1]):
        used = w[:, c] > 0
        if used.any():
            w[used, c] = np.maximum(w[used, c], 0.01 * np.median(w[used, c]))
    for c in range(w.shape[1]):
        if np.sum(w[:, c] > 0) < order + 1:
            finite = np.isfinite(variances[:, c])
            w[:, c] = finite if finite.sum() >= order + 1 else 1.0
        w[:, c] /= np.mean(w[w[:, c] > 0, c])
    return w


def midpoint_nodes(
    times: np.ndarray, poses: np.ndarray, order: int = 3
) -> tuple[np.ndarray, np.ndarray]:
    """The curve's nodes from the epochs' poses: the poses (N - 1, 4, 4) at the middle of
    every interval between epochs, with their times (N - 1,) s (N: epochs).

    Why the middle: an epoch's planes are seen, on average, halfway through it, so its
    estimated pose is only as good as what the planes fix there; a pose sequence whose
    steps err alternately by +e and -e (a sawtooth) puts every mid-epoch pose right, and
    deskews its epochs into planes that reproduce it (measured on the simulated paper loop
    at sigma = 0: the streaming pass leaves such a roll sawtooth of +-0.015 deg, which
    a pass deskewing through the epoch poses keeps). The polynomial's value at the
    middle cancels the sawtooth exactly (cubic weights -1/16, 9/16, 9/16, -1/16) and is
    exact for a polynomial motion, so the curve through these nodes is too.
    """
    times = np.asarray(times, dtype=np.float64)
    mid = 0.5 * (times[1:] + times[:-1])
    out = np.array([curve_poses(times, poses, m, np.array([m]), order)[0] for m in mid])
    return mid, out.reshape(-1, 4, 4)


def epoch_middles(times: np.ndarray) -> np.ndarray:
    """The middle of every epoch (N,) s: halfway to the next epoch's time (the last one:
    half its previous interval on; a single epoch: its time)."""
    times = np.asarray(times, dtype=np.float64)
    if len(times) < 2:
        return times.copy()
    step = np.diff(times)
    return times + 0.5 * np.r_[step, step[-1]]


def interpolated_motion(
    node_times: np.ndarray,
    node_poses: np.ndarray,
    t_ref: float,
    t: np.ndarray,
    order: int = 3,
    variances: np.ndarray | None = None,
    n_fit: int | None = None,
    increments: bool = False,
) -> np.ndarray:
    """``T_ref_t`` (T, 4, 4): the base frame at the absolute times ``t`` (T,) s in the one
    at ``t_ref`` (s), on the curve through the nodes (:func:`curve_poses`, with its
    ``variances``, ``n_fit`` and ``increments``)."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    around = 0.5 * (float(np.min(t)) + float(np.max(t))) if len(t) else t_ref
    T = curve_poses(
        node_times, node_poses, around, np.r_[t_ref, t], order, variances, n_fit, increments
    )
    return invert_transform(T[0]) @ T[1:]


def deskew_with_poses(
    scan: Scan,
    node_times: np.ndarray,
    node_poses: np.ndarray,
    t_k: float,
    order: int = 3,
    t_ref: float | None = None,
    variances: np.ndarray | None = None,
    n_fit: int | None = None,
    increments: bool = False,
) -> Scan:
    """A scan of the epoch at ``t_k`` (s) with every point (seen at ``t_k + scan.t``)
    brought to the base frame at ``t_ref`` (s, default ``t_k``) by the motion on the
    curve through the nodes (:func:`interpolated_motion`; nodes from
    :func:`midpoint_nodes`); its times become zero (the points are deskewed). A scan
    without times is returned unchanged.

    Args:
        scan: the epoch's points, each in the base frame of its own time (``scan.t``).
        node_times: (J,) seconds. node_poses: (J, 4, 4) ``T_world_base``.
        variances, n_fit, increments: the least-squares fit instead of the interpolation
            (:func:`curve_poses`).
    """
    if scan.t is None or len(scan.t) == 0:
        return scan
    # one transform per distinct time: a 2D scanner's sweep shares none, but a spinning
    # lidar's column does
    t_unique, inverse = np.unique(scan.t, return_inverse=True)
    reference = t_k if t_ref is None else t_ref
    T = interpolated_motion(
        node_times, node_poses, reference, t_k + t_unique, order, variances, n_fit, increments
    )
    T = T[inverse.reshape(-1)]
    points = np.einsum("nij,nj->ni", T[:, :3, :3], scan.points) + T[:, :3, 3]
    return replace(scan, points=points, t=np.zeros_like(scan.t))


def curve_steps(
    node_times: np.ndarray,
    node_poses: np.ndarray,
    times: np.ndarray,
    order: int = 3,
    variances: np.ndarray | None = None,
    n_fit: int | None = None,
    increments: bool = False,
) -> np.ndarray:
    """The steps ``T_{k-1}_k`` (N - 1, 4, 4) between consecutive ``times`` (N,) s along
    the curve through the nodes (:func:`curve_poses`, with its ``variances``, ``n_fit``
    and ``increments``), each from the one polynomial around the middle of its interval."""
    times = np.asarray(times, dtype=np.float64)
    out = np.empty((max(len(times) - 1, 0), 4, 4))
    for k in range(1, len(times)):
        pair = times[k - 1 : k + 1]
        T = curve_poses(node_times, node_poses, float(pair.mean()), pair, order, variances,
                        n_fit, increments)  # fmt: skip
        out[k - 1] = invert_transform(T[0]) @ T[1]
    return out
