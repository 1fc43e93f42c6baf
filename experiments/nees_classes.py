"""Which factors' true errors make a smoothed lap's pose errors (a diagnostic, issue 14).

At the batch's estimate ``x`` (with loops, default covariances, the lap as
``nees_gauge.py`` builds it) the graph's whitened errors at the truth ``r(t)`` give the
error to first order: ``J^T r(x) = 0`` so ``t - x = A^-1 J^T r(t)``, ``A = J^T J`` (the
covariance graph's Jacobian ``J``, robust factors with their weight at ``x``). Split by
factor class ``c`` (plane factors, 5-DoF between factors, priors, the rest) the response
``d_c = A^-1 J_c^T r_c(t)`` sums to the error; the plane factors' errors are split again
into the part their epoch's common deskewing error explains (``e_k``: least squares over
the epoch's planes against the true surfaces through their ``deskew_jacobian``, as
``nees_gauge.py``; ``plane_error_map`` maps it into each factor's whitened error) and the
rest. The truth: the true poses relative to the first, each landmark the true surface of
its observations' most common ``truth_id`` (in its anchor's frame for an anchored one; the
anchor itself and landmarks whose surface is more than 0.1 rad off the estimate kept at
the estimate). Printed per class: the mean NEES5 of ``d_c`` and of the error without it,
and per component the mean ``d^2 / P_ii``.

    uv run python experiments/nees_classes.py --world 146 --noise 0.02 --cache DIR
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import gtsam
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402  (patches the batch to capture its graph)

from planodom.geometry import invert_transform, transform_planes  # noqa: E402
from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.batch_covariances import covariance_graph  # noqa: E402
from planodom.smoothing.graph import X  # noqa: E402
from planodom.smoothing.sandwich import covariance_graph_index, plane_error_map  # noqa: E402


def symbol(key: int) -> tuple[str, int]:
    s = gtsam.Symbol(key)
    c = s.chr()
    return (chr(c) if isinstance(c, int) else str(c)).lower(), int(s.index())


def true_values(est, cov_graph, planes, gt, full) -> gtsam.Values:  # noqa: ANN001
    """The estimate with the poses and plane landmarks set to the truth."""
    truth = gtsam.Values(est)
    for k in range(len(gt)):
        truth.update(X(k), gtsam.Pose3(gt[k]))
    scene = full.scene
    n0, d0 = transform_planes(invert_transform(full.poses[0]), scene.normals, scene.offsets)
    ids = {int(i): j for j, i in enumerate(scene.ids)}
    votes: dict[int, Counter] = {}
    anchor: dict[int, int | None] = {}
    for i, (_, plane) in planes.items():
        keys = list(cov_graph.at(i).keys())
        lm = next(k for k in keys if symbol(k)[0] == "l")
        anchor[lm] = next((k for k in keys if symbol(k)[0] == "a"), None)
        if plane.truth_id in ids:
            votes.setdefault(lm, Counter())[int(plane.truth_id)] += 1
    kept = off = 0
    for lm, c in votes.items():
        j = ids[c.most_common(1)[0][0]]
        world = np.append(n0[j], d0[j])
        a = anchor.get(lm)
        if a is not None:
            T = est.atPose3(a).matrix()
            n, d = transform_planes(invert_transform(T), n0[j][None], np.array([d0[j]]))
            world = np.append(n[0], d[0])
        current = np.asarray(est.atOrientedPlane3(lm).planeCoefficients())
        if world[:3] @ current[:3] < 0:
            world = -world
        if np.arccos(min(1.0, float(world[:3] @ current[:3]))) > 0.1:
            off += 1
            continue
        truth.update(lm, gtsam.OrientedPlane3(world))
        kept += 1
    print(f"landmarks set to the truth {kept}, left at the estimate {off}")
    return truth


def whitened_at(factor, est, truth) -> tuple[np.ndarray, tuple]:  # noqa: ANN001
    """(whitened error at the truth with the robust weight at ``est``, the linearised
    factor's (A, b) at ``est``)."""
    noise = factor.noiseModel()
    lin = factor.linearize(est)
    A, b = lin.jacobian()
    err = np.asarray(factor.unwhitenedError(truth))
    if isinstance(noise, gtsam.noiseModel.Robust):
        base = noise.noise()
        w0 = np.linalg.norm(base.whiten(np.asarray(factor.unwhitenedError(est))))
        scale = np.linalg.norm(b) / w0 if w0 > 0 else 1.0
        return scale * base.whiten(err), (A, b)
    return np.asarray(noise.whiten(err)), (A, b)


def factor_class(factor) -> str:  # noqa: ANN001
    keys = [symbol(k)[0] for k in factor.keys()]
    if "l" in keys:
        return "plane"
    if keys == ["x"]:
        return "pose prior"
    if all(k == "x" for k in keys) and factor.dim() in (5, 6, 3):
        return f"between{factor.dim()}"
    return "other " + "".join(sorted(set(keys))) + str(factor.dim())


def report_betweens(betweens: list[tuple[int, int, float, int]]) -> None:
    """The between factors' squared whitened errors at the truth per dimension, by delta."""
    b = np.array(betweens)
    for dim in (3, 5):
        m = b[:, 3] == dim
        if not m.any():
            continue
        print(f"  between{dim}: chi2/dof at the truth mean {np.mean(b[m, 2] / dim):.2f} "
              f"median {np.median(b[m, 2] / dim):.2f} (n {m.sum()})")  # fmt: skip
        gap = b[:, 1] - b[:, 0]
        for name, md in (("delta 1-3", m & (gap <= 3)), ("loops", m & (gap > 3))):
            if md.any():
                print(f"    {name}: n {md.sum():5d} chi2/dof mean {np.mean(b[md, 2] / dim):.2f} "
                      f"median {np.median(b[md, 2] / dim):.2f}")  # fmt: skip
        first = b[m & (b[:, 0] < 3)]
        print("    from epochs 0-2 (prev, curr, chi2):",
              " ".join(f"{int(a)}-{int(c)}:{x:.1f}" for a, c, x, _ in first))  # fmt: skip


def main() -> None:
    args = nees_gauge.lap_parser(__doc__.splitlines()[0]).parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    res = smooth_batch(odo.planes, rel, cfg)
    E = len(gt)
    cap = nees_gauge.CAPTURED
    est, graph = cap["estimate"], cap["graph"]
    cov_graph = covariance_graph(
        graph, cap["gaussian"], est, cap["builder"].config.covariance_inlier_quantile
    )
    index = covariance_graph_index(graph, cov_graph)
    planes = {index[i]: obs for i, obs in cap["planes"].items() if i in index}
    truth = true_values(est, cov_graph, planes, gt, full)
    desk = np.full((E, 6), np.nan)
    for k in range(E):
        desk[k] = nees_gauge.plane_deskew_error(odo.planes[k], full.poses[k], full.scene)[0]
    # columns
    zero = est.zeroVectors()
    offsets, n_cols = {}, 0
    for key in est.keys():
        offsets[key] = n_cols
        n_cols += zero.at(key).size
    rows, cols, vals = [], [], []
    rhs: dict[str, list] = {}
    betweens: list[tuple[int, int, float, int]] = []
    n_rows = 0
    for i in range(cov_graph.size()):
        f = cov_graph.at(i)
        if f is None:
            continue
        r, (A, b) = whitened_at(f, est, truth)
        m = A.shape[0]
        c0 = 0
        for key in f.keys():
            dim = zero.at(key).size
            block = A[:, c0 : c0 + dim]
            rr, cc = np.nonzero(block)
            rows.append(n_rows + rr)
            cols.append(offsets[key] + cc)
            vals.append(block[rr, cc])
            c0 += dim
        name = factor_class(f)
        if name.startswith("between"):
            ks = sorted(symbol(k)[1] for k in f.keys())
            betweens.append((ks[0], ks[1], float(r @ r), len(r)))
            name += " from x0" if ks[0] == 0 else " from x1-9" if ks[0] < 10 else ""
        parts = {name: r}
        if i in planes:
            epoch, plane = planes[i]
            g = plane_error_map(f, plane)
            tag = "plane e0" if epoch == 0 else "plane"
            parts = {f"{tag}: no Jacobian": r}
            if g is not None and np.all(np.isfinite(desk[epoch])):
                de = g @ desk[epoch]
                parts = {f"{tag}: deskew e_k": de, f"{tag}: rest": r - de}
        for name, v in parts.items():
            rhs.setdefault(name, []).append((n_rows, v))
        n_rows += m
    J = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_rows, n_cols)
    )
    H = (J.T @ J).tocsc() + 1e-12 * sp.identity(n_cols, format="csc")
    solve = spla.factorized(H)
    xi = pose_errors(res.poses, gt)
    P = res.covariances
    assert P is not None, res.covariance_note
    n5 = errors_nees(xi[1:], P[1:], range(5))
    print(f"world {args.world} noise {args.noise} epochs {E} mean NEES5 {np.nanmean(n5):.2f}")
    total = np.zeros((E, 6))
    sig2 = np.diagonal(P[1:], axis1=1, axis2=2)
    for name, pieces in sorted(rhs.items()):
        r = np.zeros(n_rows)
        for start, v in pieces:
            r[start : start + len(v)] = v
        d = solve(J.T @ r)
        dx = np.array([d[offsets[X(k)] : offsets[X(k)] + 6] for k in range(E)])
        total += dx
        own = errors_nees(dx[1:], P[1:], range(5))
        without = errors_nees(xi[1:] - dx[1:], P[1:], range(5))
        comp = np.mean(dx[1:, :5] ** 2 / sig2[:, :5], axis=0)
        print(f"  {name:22s} factors {len(pieces):6d} NEES5 of its response {np.nanmean(own):8.2f} "
              f"error without it {np.nanmean(without):8.2f}  d^2/P (r p y x y) "
              + " ".join(f"{c:.1f}" for c in comp))  # fmt: skip
    report_betweens(betweens)
    lin = errors_nees(total[1:], P[1:], range(5))
    resid = errors_nees(xi[1:] - total[1:], P[1:], range(5))
    print(
        f"  sum of the responses: NEES5 {np.nanmean(lin):.2f}; "
        f"error less the sum {np.nanmean(resid):.2f}"
    )


if __name__ == "__main__":
    main()
