"""The loop factors' error at the truth split by both ends' deskewing (a diagnostic,
issue 14, NEESFIRST; extends ``loop_deskew_check.py``).

The lap as ``nees_gauge.py`` (``--cache DIR``), the batch with loops once; per loop factor
``X(a) - X(b)``: its error at the true poses (rad, m) and sigmas, its chi2/dof there, and
the parts predicted by the older epoch a's and the younger epoch b's planes' least-squares
deskewing errors against the true surfaces (``nees_gauge.plane_deskew_error``) through
the factor's Jacobian (:mod:`planodom.smoothing.loop_deskew`; b's through the inverse
relative pose), with the chi2/dof of what is left, and the true surfaces (``truth_id``)
of its associated plane pairs, and the pairs' whitened misfit at the measured and at the
true relative pose; and the relative pose refitted over its pairs (weighted least squares)
with its misfit and its error at the truth.

    uv run python experiments/loop_ends_check.py --world 156 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402  (patches the batch to capture its graph)

from planodom.geometry import invert_transform  # noqa: E402
from planodom.smoothing.graph import X  # noqa: E402
from planodom.smoothing.loop_deskew import error_change, relative_pose_change  # noqa: E402
from planodom_factors.pose5 import pose5_error  # noqa: E402


def adjoint(T: np.ndarray) -> np.ndarray:
    """(6, 6) the adjoint of ``T`` for twists ``(omega, v)``."""
    R, t = T[:3, :3], T[:3, 3]
    skew = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    out = np.zeros((6, 6))
    out[:3, :3] = R
    out[3:, :3] = skew @ R
    out[3:, 3:] = R
    return out


def _weighted_pairs(T_a_b: np.ndarray, planes_a, planes_b, pairs: np.ndarray, flip: bool):  # noqa: ANN001, ANN202
    """Per associated pair with covariances: ``(plane b, r, W)``, ``r = pi_a - T_a_b pi_b``
    in (n, d) (b's normal flipped to a's side when ``flip``), ``W`` the pseudo-inverse of
    both planes' covariance in a's frame (as :mod:`.loop_deskew` weighs)."""
    JT = np.eye(4)
    JT[:3, :3] = T_a_b[:3, :3]
    JT[3, :3] = -(T_a_b[:3, 3] @ T_a_b[:3, :3])
    for i, j in np.asarray(pairs, dtype=int).reshape(-1, 2):
        pa, pb = planes_a[i], planes_b[j]
        if pa.covariance is None or pb.covariance is None:
            continue
        n_b = T_a_b[:3, :3] @ pb.normal
        d_b = pb.offset - n_b @ T_a_b[:3, 3]
        if flip and n_b @ pa.normal < 0:
            n_b, d_b = -n_b, -d_b
        r = np.append(pa.normal - n_b, pa.offset - d_b)
        W = np.linalg.pinv(np.asarray(pa.covariance) + JT @ np.asarray(pb.covariance) @ JT.T,
                           rcond=1e-9, hermitian=True)  # fmt: skip
        yield pb, r, W


def pair_cost(T_a_b: np.ndarray, planes_a, planes_b, pairs: np.ndarray) -> float:  # noqa: ANN001
    """Sum over the associated pairs of ``r^T W r`` (:func:`_weighted_pairs`)."""
    return sum(
        float(r @ W @ r) for _, r, W in _weighted_pairs(T_a_b, planes_a, planes_b, pairs, True)
    )


def refit(T_a_b: np.ndarray, planes_a, planes_b, pairs: np.ndarray, iters: int = 10) -> np.ndarray:  # noqa: ANN001
    """``T_a_b`` refitted by Gauss-Newton to the associated pairs (weighted least squares,
    the weights of :func:`pair_cost`; right tangent, :func:`.loop_deskew.pair_jacobian`)."""
    from types import SimpleNamespace

    from planodom.se3 import se3_exp
    from planodom.smoothing.loop_deskew import pair_jacobian

    T = np.array(T_a_b, dtype=float)
    planes_b = list(planes_b)
    for _, j in np.asarray(pairs, dtype=int).reshape(-1, 2):  # normals as the pairs join
        pb = planes_b[j]
        if (T[:3, :3] @ pb.normal) @ planes_a[_].normal < 0:
            planes_b[j] = SimpleNamespace(
                normal=-pb.normal, offset=-pb.offset, covariance=pb.covariance
            )
    for _ in range(iters):
        H, g = np.zeros((6, 6)), np.zeros(6)
        for pb, r, W in _weighted_pairs(T, planes_a, planes_b, pairs, False):
            K = -pair_jacobian(T, pb)
            H += K.T @ W @ K
            g += K.T @ W @ r
        step = -np.linalg.pinv(H, rcond=1e-9, hermitian=True) @ g
        T = T @ se3_exp(step)
        if np.linalg.norm(step) < 1e-12:
            break
    return T


def main() -> None:
    args = nees_gauge.lap_parser(__doc__.splitlines()[0]).parse_args()
    (world, full, cfg, odo, rel, gt), builder, est, cov_graph, index = nees_gauge.captured_batch(
        args
    )
    errs: dict[int, np.ndarray] = {}

    def e_of(k: int) -> np.ndarray:
        if k not in errs:
            errs[k] = nees_gauge.plane_deskew_error(odo.planes[k], full.poses[k], full.scene)[0]
        return errs[k]

    tot = np.zeros(4)
    for f in builder.loop_factors:
        i = index.get(f.factor)
        if f.removed or i is None or f.associations is None:
            continue
        factor = cov_graph.at(i)
        noise = factor.noiseModel()
        R = np.asarray(noise.R())
        T = np.asarray(f.T_old_curr, dtype=float)
        raw = np.asarray(f.truth_error(gt))
        w = R @ raw
        Ta, Tb = (est.atPose3(X(k)).matrix() for k in (f.old, f.epoch))
        E = error_change(T, Ta, Tb, factor.dim())
        Ma = relative_pose_change(T, builder.planes[f.old], builder.planes[f.epoch], f.associations)
        Tba = invert_transform(T)
        Mb = relative_pose_change(
            Tba, builder.planes[f.epoch], builder.planes[f.old], f.associations[:, ::-1]
        )
        pa = np.zeros_like(w) if Ma is None else R @ E @ Ma @ e_of(f.old)
        pb = np.zeros_like(w) if Mb is None else -R @ E @ adjoint(Tba) @ Mb @ e_of(f.epoch)
        sig = np.sqrt(np.diag(np.linalg.inv(R.T @ R)))
        d = len(w)
        chis = [w @ w / d, pa @ pa / d, pb @ pb / d, (w - pa - pb) @ (w - pa - pb) / d]
        tot += chis
        pa_, pb_ = builder.planes[f.old], builder.planes[f.epoch]
        T_true = invert_transform(gt[f.old]) @ gt[f.epoch]
        fits = [pair_cost(Tx, pa_, pb_, f.associations) for Tx in (T, T_true)]
        T_fit = refit(T, pa_, pb_, f.associations)
        fit_err = pose5_error(T_fit, gt[f.old], gt[f.epoch])[0]
        misfit = pair_cost(T_fit, pa_, pb_, f.associations)
        print(f"    refitted over its pairs: misfit {misfit:.1f}, "
              f"error at the truth {np.round(fit_err * 1e3, 2)} (mrad, mm)")  # fmt: skip
        dof = 4 * len(f.associations)
        print(f"    pairs' chi2 (whitened, both planes' covariances) at the measured "
              f"{fits[0]:.1f}, at the true relative pose {fits[1]:.1f}; dof {dof}")  # fmt: skip
        ids = " ".join(f"{pa_[i].truth_id}/{pb_[j].truth_id}" for i, j in f.associations)
        print(f"  {f.old}-{f.epoch}: err {np.round(raw * 1e3, 2)} sigma {np.round(sig * 1e3, 2)} "
              f"(mrad, mm) chi2/dof {chis[0]:.1f}, a's part {chis[1]:.1f}, b's {chis[2]:.1f}, "
              f"rest {chis[3]:.1f}; pairs' true surfaces {ids}")  # fmt: skip
    n = sum(1 for f in builder.loop_factors if not f.removed)
    print(f"world {args.world} noise {args.noise}: mean over {n} loop factors chi2/dof "
          f"{tot[0] / max(n, 1):.2f}, a's {tot[1] / max(n, 1):.2f}, "
          f"b's {tot[2] / max(n, 1):.2f}, rest {tot[3] / max(n, 1):.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
