"""Every epoch's planes against the truth under the sandwich's deskewing sizes ``Q_k``,
"run" (the default) against "epoch" (a diagnostic, issue 14, NEESRUN).

For one lap (as ``nees_gauge.py``; ``--cache DIR`` reuses the odometry, no batch is run):
per epoch its planes' whitened errors against the true surfaces under ``I + A Q_k A^T``
(``nees_where.plane_chis``' ``chi_Q``; chi2 of the stack's dof if ``Q_k`` is right) with
``smoothing.sandwich_motion_scale`` "run" and "epoch" (and ``Q = 0``, the planes alone).
Printed per model: the sum of chi over the sum of dof, the median epoch's chi / dof, the
share of epochs above chi2's 95 % quantile (0.05 if the model is right), the first
epoch's chi / dof, and the median over epochs of ``tr(A Q_k A^T) / dof`` (the modelled
deskewing variance per whitened plane row).

Then, per axis over the epochs whose planes fix all six components, the run-level scale's
input ``d_k`` (:func:`planodom.smoothing.deskew_scale.deskew_differences`) against the
least-squares deskewing error ``e_k`` the planes give against the true surfaces: rms and
median |.| of each, the planes' own sigma of ``e_k`` (median), their correlation, and the
median sigma the steps' declared covariances give their part of ``d_k``.

    uv run python experiments/deskew_epoch_sizes.py --world 38 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.stats import chi2

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402
import nees_where  # noqa: E402

from planodom.smoothing.batch_covariances import sandwich_inputs  # noqa: E402
from planodom.smoothing.deskew_scale import deskew_differences  # noqa: E402

AXES = ("roll", "pitch", "yaw", "x", "y", "z")


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    E = len(gt)
    flat = [(k, p) for k in range(E) for p in odo.planes[k]]
    planes = dict(enumerate(flat))  # every epoch's planes ("epoch" reads them all)
    models = {}
    for value in ("run", "epoch"):
        c = cfg.updated({"smoothing.sandwich_motion_scale": value}).smoothing
        Q, _ = sandwich_inputs(c, planes, rel, E)
        assert Q is not None
        models[value] = Q
    models["planes"] = np.zeros_like(models["run"])
    print(f"world {args.world} noise {args.noise} epochs {E}")
    for name, Q in models.items():
        chis, dofs, added, first, first_e = [], [], [], np.nan, np.nan
        proj, ranks = [], []
        for k in range(E):
            out = nees_where.plane_chis(odo.planes[k], full.poses[k], full.scene, Q[k])
            chi_q, dof = out[1], out[3]
            if not dof or not np.isfinite(chi_q):
                continue
            AtA, e = out[8], out[7]
            w, V = np.linalg.eigh(AtA)
            V, w = V[:, w > 1e-9 * w.max()], w[w > 1e-9 * w.max()]
            er = V.T @ e  # the deskewing error the planes fix, and its covariance
            S = V.T @ Q[k] @ V + np.diag(1.0 / w)
            proj.append(float(er @ np.linalg.solve(S, er)))
            ranks.append(len(w))
            chis.append(chi_q)
            dofs.append(dof)
            added.append(float(np.trace(AtA @ Q[k])) / dof)
            if k == 0:
                first = chi_q / dof
                first_e = proj[-1] / ranks[-1]
        c, f = np.array(chis), np.array(dofs)
        above = np.mean(c > chi2.ppf(0.95, f))
        pe, r = np.array(proj), np.array(ranks)
        print(
            f"  {name:6s} planes: chi/dof median {np.median(c / f):.3g} >95% {above:.3f} "
            f"epoch0 {first:.3g} added/dof {np.median(added):.3g} ({len(c)} epochs)\n"
            f"         e_k: chi/rank median {np.median(pe / r):.3g} mean {np.mean(pe / r):.3g} "
            f">95% {np.mean(pe > chi2.ppf(0.95, r)):.3f} <5% {np.mean(pe < chi2.ppf(0.05, r)):.3f} "
            f"epoch0 {first_e:.3g}"
        )

    differences(odo, full, rel, E)


def differences(odo, full, rel, E: int) -> None:  # noqa: ANN001
    """The module docstring's ``d_k`` against ``e_k`` per axis."""
    d, var = deskew_differences(rel, E)
    rows = []
    for k in range(E):
        out = nees_where.plane_chis(odo.planes[k], full.poses[k], full.scene, np.zeros((6, 6)))
        if out[3] and out[6] == 6:
            fit_var = np.diag(np.linalg.inv(out[8]))
            rows.append((out[7], d[k], fit_var, var[k]))
    e, dd, fit, step = (np.array(x) for x in zip(*rows, strict=True))
    print(f"  d_k against e_k ({len(e)} epochs with all six fixed; rad, m):")
    for i, axis in enumerate(AXES):
        ok = np.isfinite(dd[:, i])
        a, b = e[ok, i], dd[ok, i]
        print(
            f"   {axis:5s} e rms {np.sqrt(np.mean(a**2)):.3g} med|e| {np.median(np.abs(a)):.3g} "
            f"planes' sigma {np.median(np.sqrt(fit[ok, i])):.3g}  d rms "
            f"{np.sqrt(np.mean(b**2)):.3g} med|d| {np.median(np.abs(b)):.3g}  corr "
            f"{np.corrcoef(a, b)[0, 1]:.2f}  steps' sigma {np.median(np.sqrt(step[ok, i])):.3g}"
        )


if __name__ == "__main__":
    main()
