"""Which factors' errors at the truth exceed their modelled covariance, per kind (issue 14).

The lap as ``nees_gauge.py`` builds it (``--cache DIR`` reuses the odometry), the batch
with loops with the default covariances. At the batch's covariance graph each factor's
whitened error at the truth ``r`` (as ``nees_classes.py``: true poses relative to the
first, landmarks on their true surfaces) is compared with the covariance the sandwich
gives it: ``I + g Q_k g^T`` for a plane factor with a deskewing map ``g`` into its epoch's
column ``k`` (``Q`` the run's :func:`.batch_covariances.sandwich_inputs`), ``I`` for the
others (the default's "independent" loop factors). Per kind (the prior; the fallback;
steps: two poses at most ``smoothing.delta_max`` apart, 5-DoF or rotation-only; loop
factors beyond; plane factors, epoch 0's apart; anchors; the rest) printed: the factors,
their dimensions, the mean and median of ``r^T r / m`` (chi2 per dof, whitened by the
factor's own noise), the model's mean ``(m + tr(g Q g^T)) / m``, the mean and median of
``r^T (I + g Q g^T)^-1 r / m`` (1 where the model is right) and the share of factors above
chi2(m)'s 95 % quantile under the model (0.05 where it is right). With ``--steps``, the
rotation-only steps and the 5-DoF steps by delta, one line each with their worst factors.

    uv run python experiments/factor_truth_chi2.py --world 154 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.stats import chi2

sys.path.insert(0, str(Path(__file__).parent))
import nees_classes  # noqa: E402  (imports nees_gauge, which patches the batch)
import nees_gauge  # noqa: E402

from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.batch_covariances import covariance_graph  # noqa: E402
from planodom.smoothing.graph import X  # noqa: E402
from planodom.smoothing.loop_deskew import error_change  # noqa: E402
from planodom.smoothing.relative_deskew import pair_fit_changes  # noqa: E402
from planodom.smoothing.sandwich import covariance_graph_index, plane_error_map  # noqa: E402


def kind_of(factor, i: int, fallback: set[int], delta_max: int, planes: dict) -> str:  # noqa: ANN001
    """The factor's kind (module docstring)."""
    keys = [nees_classes.symbol(k) for k in factor.keys()]
    chars = sorted(c for c, _ in keys)
    if i in planes:
        return "plane e0" if planes[i][0] == 0 else "plane"
    if i in fallback:
        return "fallback"
    if chars == ["x"]:
        return "pose prior"
    if chars == ["x", "x"] and factor.dim() in (3, 5):
        gap = abs(keys[0][1] - keys[1][1])
        name = "loop" if gap > delta_max else "step"
        return name + (" rot-only" if factor.dim() == 3 else "")
    return "other " + "".join(sorted(set(chars))) + str(factor.dim())


def end_maps(f, est, T, planes_a, planes_b, pairs):  # noqa: ANN001, ANN201
    """(g_a, g_b) of :mod:`planodom.smoothing.relative_deskew` for factor ``f`` (either
    None), or (None, None) for a non-Gaussian noise model or no associations."""
    import gtsam

    noise = f.noiseModel()
    if pairs is None or len(pairs) == 0 or not isinstance(noise, gtsam.noiseModel.Gaussian):
        return None, None
    a, b = sorted(nees_classes.symbol(k)[1] for k in f.keys())
    M_a, M_b = pair_fit_changes(T, planes_a, planes_b, pairs)
    Ta, Tb = (est.atPose3(X(k)).matrix() for k in (a, b))
    RE = np.asarray(noise.R()) @ error_change(T, Ta, Tb, f.dim())
    return (None if M_a is None else RE @ M_a), (None if M_b is None else RE @ M_b)


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--steps", action="store_true", help="steps by delta, worst factors")
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    res = smooth_batch(odo.planes, rel, cfg)
    cap = nees_gauge.CAPTURED
    est, graph, builder = cap["estimate"], cap["graph"], cap["builder"]
    cov_graph = covariance_graph(
        graph, cap["gaussian"], est, builder.config.covariance_inlier_quantile
    )
    index = covariance_graph_index(graph, cov_graph)
    planes = {index[i]: obs for i, obs in cap["planes"].items() if i in index}
    fallback = {index[i] for i in cap["fallback"] if i in index}
    truth = nees_classes.true_values(est, cov_graph, planes, gt, full)
    Q = nees_gauge.CAPTURED_Q()
    xi = pose_errors(res.poses, gt)
    assert res.covariances is not None, res.covariance_note
    n5 = np.nanmean(errors_nees(xi[1:], res.covariances[1:], range(5)))
    print(f"world {args.world} noise {args.noise} epochs {len(gt)} mean NEES5 {n5:.2f} "
          f"model {res.covariance_model}")  # fmt: skip
    rels = {(r.prev, r.curr): r for r in cap["rel"] if r.status.value in ("ok", "degenerate")}
    loops = {index[lf.factor]: lf for lf in getattr(builder, "loop_factors", ())
             if not lf.removed and lf.factor in index}  # fmt: skip
    rows: dict[str, list[tuple[float, float, float, int, str]]] = {}
    alt: dict[str, list[tuple[float, float, int]]] = {}
    for i in range(cov_graph.size()):
        f = cov_graph.at(i)
        if f is None:
            continue
        r, _ = nees_classes.whitened_at(f, est, truth)
        m = len(r)
        C = np.eye(m)
        if i in planes:
            epoch, plane = planes[i]
            g = plane_error_map(f, plane)
            if g is not None:
                C = C + g @ Q[epoch] @ g.T
        kind = kind_of(f, i, fallback, builder.config.delta_max, planes)
        if kind.startswith(("step", "loop")):
            ea, eb = sorted(nees_classes.symbol(k)[1] for k in f.keys())
            source = None
            if i in loops:
                source = (np.asarray(loops[i].T_old_curr), loops[i].associations)
            elif (ea, eb) in rels:
                source = (rels[ea, eb].T_prev_curr, rels[ea, eb].associations)
            g_a, g_b = (None, None) if source is None else end_maps(
                f, est, source[0], builder.planes[ea], builder.planes[eb], source[1])  # fmt: skip
            Ca = np.eye(m) + (0 if g_a is None else g_a @ Q[ea] @ g_a.T)
            Cb = Ca + (0 if g_b is None else g_b @ Q[eb] @ g_b.T)
            alt.setdefault(kind, []).append(
                (float(r @ np.linalg.solve(Ca, r)) / m, float(r @ np.linalg.solve(Cb, r)) / m, m)
            )
        own = float(r @ r) / m
        model = float(r @ np.linalg.solve(C, r)) / m
        label = "-".join(str(s[1]) for s in map(nees_classes.symbol, f.keys()))
        if kind.startswith("step"):
            ks = sorted(nees_classes.symbol(k)[1] for k in f.keys())
            kind_d = f"{kind} delta {ks[1] - ks[0]}"
            rows.setdefault("~" + kind_d, []).append((own, float(np.trace(C)) / m, model, m, label))
        rows.setdefault(kind, []).append((own, float(np.trace(C)) / m, model, m, label))
    print(f"{'kind':24s} {'n':>6s} {'dof':>7s} {'own mean':>9s} {'median':>7s} "
          f"{'model E':>8s} {'norm mean':>9s} {'median':>7s} {'>95%':>6s}")  # fmt: skip
    for kind in sorted(rows):
        if kind.startswith("~") and not args.steps:
            continue
        a = np.array([x[:4] for x in rows[kind]])
        over = np.mean([x[2] * x[3] > chi2.ppf(0.95, x[3]) for x in rows[kind]])
        print(f"{kind:24s} {len(a):6d} {int(a[:, 3].sum()):7d} {a[:, 0].mean():9.2f} "
              f"{np.median(a[:, 0]):7.2f} {a[:, 1].mean():8.2f} {a[:, 2].mean():9.2f} "
              f"{np.median(a[:, 2]):7.2f} {over:6.2f}")  # fmt: skip
        if args.steps and kind.startswith(("~", "loop")):
            worst = sorted(rows[kind], key=lambda x: -x[2])[:6]
            print("    worst:", " ".join(f"{x[4]}:{x[2]:.1f}" for x in worst))
    print("relative-pose factors normalised by their ends' deskewing maps (mean, median, >95%):")
    for kind, v in sorted(alt.items()):
        arr = np.array(v)
        cells = []
        for c in (0, 1):
            over = np.mean(arr[:, c] * arr[:, 2] > chi2.ppf(0.95, arr[:, 2]))
            cells.append(f"{arr[:, c].mean():9.2f} {np.median(arr[:, c]):7.2f} {over:5.2f}")
        print(f"  {kind:22s} n {len(arr):5d} older end {cells[0]}   both ends {cells[1]}")


if __name__ == "__main__":
    main()
