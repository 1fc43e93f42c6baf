"""Variance components of the batch graph: the noise models' scale estimated from the data.

The geodesists' a posteriori variance factor and its per-group form (variance component
estimation, Helmert / Foerstner). At the estimate the graph is linearised, whitened:
rows ``A`` (m, n), right-hand side ``b`` (m,), each row's weight ``1 / s_c`` where ``s_c``
is the variance factor of its component ``c``. With the weighted solution
``delta = H^-1 A_w^T b_w`` (``H = A_w^T A_w``) and its weighted residuals
``e = A_w delta - b_w``, each component's estimate is

    s_c <- s_c * (e_c^T e_c) / r_c,   r_c = sum over the rows of c of (1 - h_ii),

``h_ii = a_i^T H^-1 a_i`` the row's leverage (diagonal of the hat matrix; ``1 - h_ii`` its
redundancy number, summing to ``m - n`` over the whole graph), iterated until every ratio
is 1 within ``tol`` (Foerstner's iteration; one component: the a posteriori variance
factor ``v^T P v / (m - n)`` restricted to the measurements). A stiff group with few
rows (the loop factors) can cycle: its redundancy collapses as its weight grows (loop
factors 1.0 <-> 5.6 on a 2 cm lap); a component whose ratio crosses 1 takes only a power
of it from then on (halved at each crossing). Leverages are exact (a
dense inverse) for ``n <= EXACT_MAX_DIM`` and otherwise Hutchinson's estimate with
``PROBES`` seeded Rademacher vectors ``z``: ``h_ii ~ mean_z (A_w H^-1 z)_i (A_w z)_i``,
unbiased; the per-row noise averages out over a large group's rows, and a group of at
most ``EXACT_ROWS`` rows (the loop factors) gets them exactly (its Hutchinson sum came
out negative on a 2D-rig lap).

Which rows take part (:func:`factor_groups`): relative poses ("between", the 5-DoF and
rotation-only factors between epochs), plane factors ("plane", re-identifications
included) and 5-DoF loop-candidate factors ("loop") are estimated; the first pose's and
the anchors' priors (gauge), the weak vertical and fallback factors (pseudo-observations
whose sigmas are chosen, not measured), deskewed-frame ties, and robust factors the
covariances keep under their kernel (beyond ``covariance_inlier_quantile``: outliers,
down-weighted to near zero, whose redundancy number would be nearly 1 with a residual
near 0) keep their weight: ``s = 1``. Their rows still count in ``H``, so the estimated
groups' redundancy is what remains after them. Robust inliers enter with their Gaussian
twin (the graph the covariances come from, :func:`.batch_covariances.covariance_graph`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import gtsam
import numpy as np
import scipy.sparse as sp
from scipy.linalg import cho_factor, cho_solve
from scipy.sparse.linalg import splu
from scipy.stats import chi2

#: Groups whose variance factor is estimated; the others keep their weight.
ESTIMATED = ("between", "plane", "loop")
#: Exact leverages (dense Cholesky of H) up to this many unknowns, Hutchinson above.
EXACT_MAX_DIM = 1500
#: Hutchinson probes: the sampling spread of a group's redundancy is at most
#: sqrt(2 u / PROBES), u its rows' summed leverage (every h_ii lies in [0, 1]).
PROBES = 100
#: Groups with at most this many rows get exact leverages (one solve per row).
EXACT_ROWS = 600
#: A component with less redundancy than this is not estimated (keeps its factor).
MIN_REDUNDANCY = 2.0


@dataclass
class VarianceComponents:
    """What :func:`estimate_components` found.

    Attributes:
        scales: component -> variance factor ``s_c`` (multiplies its rows' covariances).
        residual: component -> weighted squared residual sum at the end (whitened by the
            original noise models: ``s_c * e_c^T e_c`` in the weighted terms).
        redundancy: component -> redundancy ``r_c`` at the end.
        rows: component -> number of rows.
        iterations: Foerstner iterations run; converged: whether the ratios reached 1.
        delta: the weighted linear solution at the end (tangent step from the estimate);
            step: its largest component.
    """

    scales: dict[str, float] = field(default_factory=dict)
    residual: dict[str, float] = field(default_factory=dict)
    redundancy: dict[str, float] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)
    iterations: int = 0
    converged: bool = False
    delta: gtsam.VectorValues | None = None
    step: float = 0.0


def _symbol(key: int) -> str:
    return chr(gtsam.Symbol(key).chr())


def factor_groups(
    graph: gtsam.NonlinearFactorGraph,
    gaussian: Mapping[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
    loop_factors: Iterable[int],
    fallback_factors: Iterable[int],
    inlier_quantile: float | None,
) -> list[str]:
    """Group label of every factor of ``graph`` that is not None, in order (the order of
    :func:`.batch_covariances.covariance_graph`'s output): "loop" (``loop_factors`` indices),
    "fallback" (``fallback_factors``), "outlier" (a robust factor whose Gaussian twin's
    squared whitened error exceeds chi2(dim) at ``inlier_quantile``; None: none, the
    covariances keep every kernel's weight), "plane" (on a landmark ``L``), "prior" (one
    key), "vertical" (one row), "between" (two pose keys, 5 or 3 rows), "other" (anything
    else, e.g. frame ties)."""
    loops, fallbacks = set(loop_factors), set(fallback_factors)
    labels: list[str] = []
    for i in range(graph.size()):
        factor = graph.at(i)
        if factor is None:
            continue
        twin = gaussian.get(i)
        if (
            twin is not None
            and inlier_quantile is not None
            and 2.0 * twin.error(values) > chi2.ppf(inlier_quantile, twin.dim())
        ):
            labels.append("outlier")
            continue
        keys = list(factor.keys())
        symbols = {_symbol(k) for k in keys}
        if i in loops:
            labels.append("loop")
        elif i in fallbacks:
            labels.append("fallback")
        elif "l" in symbols:
            labels.append("plane")
        elif len(keys) == 1:
            labels.append("prior")
        elif factor.dim() == 1:
            labels.append("vertical")
        elif len(keys) == 2 and factor.dim() in (3, 5):
            labels.append("between")
        else:
            labels.append("other")
    return labels


@dataclass
class _Sparse:
    """A linear graph's whitened rows: ``A`` (m, n) CSR, ``b`` (m,), each row's factor
    index, and the column offset and dimension of each key."""

    A: sp.csr_matrix
    b: np.ndarray
    factor: np.ndarray
    columns: dict[int, tuple[int, int]]


def _sparse(linear: gtsam.GaussianFactorGraph, dims: Mapping[int, int]) -> _Sparse:
    columns: dict[int, tuple[int, int]] = {}
    rows, cols, vals, rhs, owner = [], [], [], [], []
    m = n = 0
    for i in range(linear.size()):
        factor = linear.at(i)
        A, b = factor.jacobian()  # whitened by the factor's own model
        offset = 0
        for key in factor.keys():
            if key not in columns:
                columns[key] = (n, dims[key])
                n += dims[key]
            start, dim = columns[key]
            r, c = np.nonzero(A[:, offset : offset + dim])
            rows.append(m + r)
            cols.append(start + c)
            vals.append(A[r, offset + c])
            offset += dim
        rhs.append(np.asarray(b, dtype=float).ravel())
        owner.append(np.full(A.shape[0], i))
        m += A.shape[0]
    A = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, n)
    )
    return _Sparse(A, np.concatenate(rhs), np.concatenate(owner), columns)


def _solver(A: sp.csr_matrix) -> Callable[[np.ndarray], np.ndarray]:
    """``x -> (A^T A)^-1 x``: dense Cholesky for at most ``EXACT_MAX_DIM`` columns, else
    sparse LU."""
    H = (A.T @ A).tocsc()
    if H.shape[0] <= EXACT_MAX_DIM:
        factor = cho_factor(H.toarray())
        return lambda x: cho_solve(factor, x)
    return splu(H, permc_spec="MMD_AT_PLUS_A").solve


def leverages(
    A: sp.csr_matrix,
    solve: Callable[[np.ndarray], np.ndarray] | None = None,
    exact: np.ndarray | None = None,
    seed: int = 0,
) -> np.ndarray:
    """(m,) diagonal of the hat matrix ``A (A^T A)^-1 A^T``: exact for at most
    ``EXACT_MAX_DIM`` columns, else Hutchinson's estimate with ``PROBES`` seeded
    Rademacher vectors (see the module docstring), and exact for the rows ``exact``
    (indices; one solve each). ``solve``: :func:`_solver` of ``A``."""
    solve = solve or _solver(A)
    n = A.shape[1]
    if n <= EXACT_MAX_DIM:
        dense = A.toarray()
        return np.einsum("ij,ji->i", dense, solve(dense.T))
    Z = np.random.default_rng(seed).choice([-1.0, 1.0], size=(n, PROBES))
    h = np.asarray(np.mean(np.asarray(A @ solve(Z)) * np.asarray(A @ Z), axis=1))
    if exact is not None and len(exact):
        rows = A[exact].toarray()
        h[exact] = np.einsum("ij,ji->i", rows, solve(rows.T))
    return h


def estimate_components(
    linear: gtsam.GaussianFactorGraph,
    dims: Mapping[int, int],
    components: Sequence[str | None],
    initial: Mapping[str, float] | None = None,
    max_iterations: int = 30,
    tol: float = 1e-3,
) -> VarianceComponents:
    """Foerstner's iteration on a linear graph (module docstring).

    Args:
        linear: the whitened linear graph at the estimate (one factor per row group).
        dims: tangent dimension of every key of ``linear``.
        components: per factor of ``linear``, its component, or None (weight kept).
        initial: starting variance factors (default 1).
        max_iterations, tol: stop when every ratio is within ``tol`` of 1.
    """
    if len(components) != linear.size():
        raise ValueError(f"{len(components)} labels for {linear.size()} factors")
    system = _sparse(linear, dims)
    label = np.array([components[i] or "" for i in system.factor])
    names = sorted({c for c in components if c})
    out = VarianceComponents(scales={c: float((initial or {}).get(c, 1.0)) for c in names})
    out.rows = {c: int(np.sum(label == c)) for c in names}
    # small groups' leverages exactly (Hutchinson's noise does not average out over them)
    small = np.flatnonzero(np.isin(label, [c for c in names if out.rows[c] <= EXACT_ROWS]))
    delta = np.zeros(system.A.shape[1])
    power = dict.fromkeys(names, 1.0)  # damping: halved when a component's ratio flips side
    last: dict[str, float] = {}
    for it in range(1, max_iterations + 1):
        scale = np.ones(len(label))
        for c in names:
            scale[label == c] = out.scales[c]
        w = 1.0 / np.sqrt(scale)
        # Columns scaled to unit norm (the hat matrix is unchanged): stiff landmarks next
        # to poses held by 0.5 m fallback factors leave H = A^T A otherwise too
        # ill-conditioned for its LU (negative leverage sums on a 2D-rig lap).
        Aw = (sp.diags(w) @ system.A).tocsc()
        norms = np.sqrt(np.asarray(Aw.multiply(Aw).sum(axis=0))).ravel()
        Aw = (Aw @ sp.diags(1.0 / np.where(norms > 0.0, norms, 1.0))).tocsr()
        bw = w * system.b
        solve = _solver(Aw)
        delta = solve(Aw.T @ bw)
        e = Aw @ delta - bw
        delta = delta / np.where(norms > 0.0, norms, 1.0)
        h = leverages(Aw, solve, small)  # the same probes throughout: a fixed point
        ratios = {}
        for c in names:
            sel = label == c
            out.redundancy[c] = float(np.sum(1.0 - h[sel]))
            out.residual[c] = float(out.scales[c] * e[sel] @ e[sel])
            if out.redundancy[c] >= MIN_REDUNDANCY:
                ratios[c] = float(e[sel] @ e[sel]) / out.redundancy[c]
        out.iterations = it
        if all(abs(r - 1.0) <= tol for r in ratios.values()):
            out.converged = True
            break
        for c, r in ratios.items():
            if c in last and (r - 1.0) * (last[c] - 1.0) < 0.0:
                power[c] /= 2.0
            last[c] = r
            out.scales[c] *= r ** power[c]
    out.step = float(np.abs(delta).max()) if len(delta) else 0.0
    out.delta = gtsam.VectorValues()
    for key, (start, dim) in system.columns.items():
        out.delta.insert(key, delta[start : start + dim])
    return out


def scaled_linear(
    linear: gtsam.GaussianFactorGraph,
    components: Sequence[str | None],
    scales: Mapping[str, float],
) -> gtsam.GaussianFactorGraph:
    """A copy of ``linear`` with each factor of component ``c`` weighted by ``1 / s_c``
    (its covariance times ``s_c``); factors without a component unchanged."""
    out = gtsam.GaussianFactorGraph()
    for i in range(linear.size()):
        factor = linear.at(i)
        c = components[i]
        if c is None or scales.get(c, 1.0) == 1.0:
            out.push_back(factor)
            continue
        A, b = factor.jacobian()
        copy = gtsam.JacobianFactor(factor)
        copy.setModel(False, np.full(A.shape[0], np.sqrt(scales[c])))
        out.push_back(copy)
    return out


#: ``covariance_scale_estimate`` "resolve": at most this many Gauss-Newton steps.
RESOLVE_STEPS = 5


def scale_noise(
    graph: gtsam.NonlinearFactorGraph,
    labels: Sequence[str],
    values: gtsam.Values,
    mode: str,
    resolve: bool,
) -> tuple[gtsam.Values, gtsam.GaussianFactorGraph, VarianceComponents]:
    """The covariance graph ``graph`` (labels from :func:`factor_groups`) reweighted by its
    variance components, linearised.

    Args:
        mode: "posterior" (the estimated groups one component) or "groups" (each its own).
        resolve: Gauss-Newton steps on the reweighted graph from ``values`` (at most
            ``RESOLVE_STEPS``, the components estimated again at each), else ``values``.

    Returns:
        The estimate, the reweighted linear graph at it (for the marginals) and the
        components.
    """
    components = [
        (c if mode == "groups" else "measurements") if c in ESTIMATED else None for c in labels
    ]
    zero = values.zeroVectors()
    dims = {key: zero.at(key).size for key in values.keys()}
    scales: dict[str, float] = {}
    for _ in range(RESOLVE_STEPS if resolve else 1):
        linear = graph.linearize(values)
        out = estimate_components(linear, dims, components, scales)
        scales = out.scales
        if not resolve:
            break
        assert out.delta is not None
        values = values.retract(out.delta)
        if out.step < 1e-9:
            break
    if resolve:  # the components at the final estimate
        linear = graph.linearize(values)
        out = estimate_components(linear, dims, components, scales)
    # The gauge priors (first pose, anchors) follow the planes: they leave the poses'
    # marginals alone, and kept at their weight beside reweighted planes they made gtsam
    # find the system indeterminant near an anchor (2D-rig lap at 6 mm, planes x 1 / 0.64).
    plane = "plane" if mode == "groups" else "measurements"
    scaling = [plane if c == "prior" else k for c, k in zip(labels, components, strict=True)]
    return values, scaled_linear(linear, scaling, out.scales), out
