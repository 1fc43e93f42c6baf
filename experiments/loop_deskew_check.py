"""The loop factors' deskewing share (``sandwich_loop_sources`` "deskew") against the
truth on one lap (issue 14, NEESJAC): a diagnostic, no test.

The lap as ``nees_gauge.py`` (``--cache DIR``), the batch with loops once; then per older
epoch a of the loop factors: its ``Q_a`` sigmas against the run's median, its planes'
least-squares deskewing error against the true surfaces (``nees_gauge.plane_deskew_error``,
``e_a``); per loop factor: its whitened error at the truth (chi2/dof), the part ``g e_a``
the model predicts from ``e_a`` (chi2/dof of it and of the rest), and the variance the
model adds (``tr(g Q_a g^T) / dim``).

    uv run python experiments/loop_deskew_check.py --world 38 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402  (patches the batch to capture its graph)

from planodom.smoothing.loop_deskew import loop_deskew_maps  # noqa: E402


def main() -> None:
    args = nees_gauge.lap_parser(__doc__.splitlines()[0]).parse_args()
    (world, full, cfg, odo, rel, gt), builder, est, cov_graph, index = nees_gauge.captured_batch(
        args
    )
    cap = nees_gauge.CAPTURED
    Q = nees_gauge.CAPTURED_Q()
    maps = loop_deskew_maps(cov_graph, est, builder.loop_factors, index, builder.planes, Q)
    sig = np.sqrt(np.diagonal(Q, axis1=1, axis2=2))
    print(f"world {args.world} noise {args.noise}: median Q sigma (rad, m)",
          np.round(np.median(sig, axis=0), 5))  # fmt: skip
    residual = _batch_deskew(cov_graph, est, cap["planes"], index)
    for k in (0, 1, 2, 3, 50, 300, 600):
        if k < len(Q) and k in residual:
            e, _, _ = nees_gauge.plane_deskew_error(odo.planes[k], full.poses[k], full.scene)
            print(f"epoch {k}: truth LS {np.round(e, 5)} batch residual LS "
                  f"{np.round(residual[k], 5)} Q sigma {np.round(sig[k], 5)}")  # fmt: skip
    errs = {}
    for a in sorted({f.old for f in builder.loop_factors}):
        e, chi, n = nees_gauge.plane_deskew_error(odo.planes[a], full.poses[a], full.scene)
        errs[a] = e
        print(f"older epoch {a}: Q sigma {np.round(sig[a], 5)}; planes' LS deskew error "
              f"{np.round(e, 5)} ({n} planes, chi2/plane before {chi:.1f})")  # fmt: skip
    for f in builder.loop_factors:
        i = index.get(f.factor)
        if i is None or i not in maps:
            print(f"  {f.old}-{f.epoch}: no map (removed {f.removed})")
            continue
        a, g = maps[i]
        R = np.asarray(cov_graph.at(i).noiseModel().R())
        w = R @ f.truth_error(gt)
        pred = g @ errs[a]
        added = np.trace(g @ Q[a] @ g.T) / len(g)
        print(f"  {a}-{f.epoch}: chi2/dof at truth {w @ w / 5:.2f}, predicted part "
              f"{pred @ pred / 5:.2f}, rest {(w - pred) @ (w - pred) / 5:.2f}, added var "
              f"{added:.3g}; whitened err {np.round(w, 2)} pred {np.round(pred, 2)}")  # fmt: skip


def _batch_deskew(cov_graph, est, planes, index) -> dict[int, np.ndarray]:  # noqa: ANN001
    """Per epoch the least-squares change of motion explaining its plane factors'
    whitened errors at the estimate through their maps (``plane_error_map``)."""
    from planodom.smoothing.sandwich import plane_error_map

    rows: dict[int, list] = {}
    for i, (epoch, plane) in planes.items():
        j = index.get(i)
        if j is None:
            continue
        g = plane_error_map(cov_graph.at(j), plane)
        if g is None:
            continue
        r = np.asarray(cov_graph.at(j).whitenedError(est))
        rows.setdefault(epoch, []).append((g, r))
    out = {}
    for epoch, gr in rows.items():
        G = np.vstack([g for g, _ in gr])
        r = np.concatenate([r for _, r in gr])
        out[epoch] = -np.linalg.lstsq(G, r, rcond=1e-9)[0]
    return out


if __name__ == "__main__":
    main()
