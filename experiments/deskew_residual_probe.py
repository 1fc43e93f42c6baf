"""Prototype: each epoch's deskewing error as its plane factors' residuals at the batch's
estimate show it, against the sandwich's ``Q_k`` and the truth (issue 14, NEESLAP).

The lap as ``nees_gauge.py`` (``--cache DIR``), the batch with loops with the default
covariances. Per epoch ``e_k = pinv(G_k) r_k``: ``r_k`` its plane factors' whitened
errors at the estimate, ``G_k`` their deskewing maps (``plane_error_map``); its excess
over the planes' own noise ``e_k^2 - diag(pinv(G_k^T G_k))``, averaged over the epochs
within two of k, is the size the residuals give. Printed: the covariances recomputed with
``Q_k`` raised to it per axis, mean NEES5 each way, and the correlation of ``e_k`` with
the truth's least-squares deskewing error.

    uv run python experiments/deskew_residual_probe.py --world 292 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import gtsam
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402  (patches the batch to capture its graph)

from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.smoothing import batch_covariances  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.batch_covariances import covariance_graph  # noqa: E402
from planodom.smoothing.sandwich import covariance_graph_index, plane_error_map  # noqa: E402

SANDWICH_INPUTS = batch_covariances.sandwich_inputs


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--half", type=int, default=2)
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    res = smooth_batch(odo.planes, rel, cfg)
    assert res.covariances is not None
    cap = nees_gauge.CAPTURED
    est, builder = cap["estimate"], cap["builder"]
    cov_graph = covariance_graph(
        cap["graph"], cap["gaussian"], est, builder.config.covariance_inlier_quantile
    )
    index = covariance_graph_index(cap["graph"], cov_graph)
    planes = {index[i]: obs for i, obs in cap["planes"].items() if i in index}
    E = len(gt)
    Gs: dict[int, list] = {}
    rs: dict[int, list] = {}
    for i, (epoch, plane) in planes.items():
        f = cov_graph.at(i)
        g = plane_error_map(f, plane)
        if g is None:
            continue
        noise = f.noiseModel()  # type: ignore[attr-defined]  # a NoiseModelFactor
        if not isinstance(noise, gtsam.noiseModel.Gaussian):
            continue
        error = f.unwhitenedError(est)  # type: ignore[attr-defined]
        r = np.asarray(noise.whiten(np.asarray(error)))
        Gs.setdefault(epoch, []).append(g)
        rs.setdefault(epoch, []).append(r)
    e_hat = np.full((E, 6), np.nan)
    excess = np.full((E, 6), np.nan)
    for k in Gs:
        G, r = np.vstack(Gs[k]), np.concatenate(rs[k])
        N = G.T @ G
        Ni = np.linalg.pinv(N, rcond=1e-9)
        e = Ni @ G.T @ r
        e_hat[k] = e
        excess[k] = e**2 - np.diag(Ni)
    Q = nees_gauge.CAPTURED_Q()
    D = np.zeros((E, 6))
    for k in range(E):
        lo, hi = max(0, k - args.half), min(E, k + args.half + 1)
        win = excess[lo:hi]
        ok = np.isfinite(win[:, 0])
        if ok.any():
            D[k] = np.maximum(win[ok].mean(axis=0), 0.0)
    Q_new = np.array(Q, copy=True)
    for k in range(E):
        q = np.diag(Q_new[k]).copy()
        add = np.maximum(D[k] - q, 0.0)
        Q_new[k] = Q_new[k] + np.diag(add)
    xi = pose_errors(res.poses, gt)
    n_def = np.nanmean(errors_nees(xi[1:], res.covariances[1:], range(5)))

    def inputs(*a, **kw):  # noqa: ANN002, ANN003, ANN202
        return Q_new, None

    batch_covariances.sandwich_inputs = inputs
    _, P_new, note, _, model = nees_gauge.ORIGINAL(
        builder, cap["graph"], cap["gaussian"], cap["fallback"], est, cap["n"], cap["planes"],
        cap["rel"],
    )  # fmt: skip
    batch_covariances.sandwich_inputs = SANDWICH_INPUTS
    assert P_new is not None, note
    n_new = np.nanmean(errors_nees(xi[1:], P_new[1:], range(5)))
    raised = np.mean([np.any(np.diag(Q_new[k]) > np.diag(Q[k]) * 1.0001) for k in range(E)])
    ratio = np.nanmedian(
        np.where(np.diagonal(Q, axis1=1, axis2=2) > 0,
                 np.diagonal(Q_new, axis1=1, axis2=2) / np.diagonal(Q, axis1=1, axis2=2), np.nan),
        axis=0)  # fmt: skip
    truth = np.full((E, 6), np.nan)
    for k in range(E):
        truth[k] = nees_gauge.plane_deskew_error(odo.planes[k], full.poses[k], full.scene)[0]
    ok = np.isfinite(truth[:, 0]) & np.isfinite(e_hat[:, 0])
    corr = [np.corrcoef(truth[ok, j], e_hat[ok, j])[0, 1] for j in range(6)]
    rms_t = np.sqrt(np.nanmean(truth[ok] ** 2, axis=0))
    rms_e = np.sqrt(np.nanmean(e_hat[ok] ** 2, axis=0))
    rms_q = np.sqrt(np.mean(np.diagonal(Q, axis1=1, axis2=2), axis=0))
    rms_qn = np.sqrt(np.mean(np.diagonal(Q_new, axis1=1, axis2=2), axis=0))
    print(f"world {args.world} noise {args.noise} epochs {E} NEES5 default {n_def:.2f} "
          f"residual {n_new:.2f} ({model}); epochs raised {raised:.2f}")  # fmt: skip
    print("  median Q ratio per axis", np.round(ratio, 2))
    print("  corr(e_hat, truth)", np.round(corr, 2))
    print("  rms truth e  ", np.array2string(rms_t, precision=6))
    print("  rms e_hat    ", np.array2string(rms_e, precision=6))
    print("  rms sqrt Q   ", np.array2string(rms_q, precision=6))
    print("  rms sqrt Qnew", np.array2string(rms_qn, precision=6))


if __name__ == "__main__":
    main()
