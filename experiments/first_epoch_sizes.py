"""The first epoch's deskewing error against the sizes the sandwich could give it (a
diagnostic, issue 14, NEESFIRST).

For one lap (as ``nees_gauge.py``; ``--cache DIR`` reuses the odometry, no batch is run):
epochs 0..``--epochs`` - 1, their deskewing error ``e_k`` (6,) against the true surfaces
(least squares over their planes through their ``deskew_jacobian``,
:func:`nees_gauge.plane_deskew_error`), and per model of its covariance the sigmas and the
whitened square ``e^T Q^-1 e`` over the axes the planes fix (chi2 of that many dof if the
model is right): "motion" the sandwich's default ``Q_k`` (the run's scaled changes of
motion), "step" the first step's declared covariance times ``(span / interval)^2``
(:func:`planodom.smoothing.first_epoch_noise.first_step_covariance`), "sum" both; and the
planes' whitened errors' squares under each (``nees_where.plane_chis``'s ``chi_Q``: the
stack against ``I + A Q A^T``, chi2 of the printed dof if the model is right).

    uv run python experiments/first_epoch_sizes.py --world 38 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402
import nees_where  # noqa: E402

from planodom.smoothing.batch_covariances import sandwich_inputs  # noqa: E402
from planodom.smoothing.first_epoch_noise import first_step_covariance  # noqa: E402

AXES = ("roll", "pitch", "yaw", "x", "y", "z")


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--epochs", type=int, default=3)
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    planes = dict(enumerate((0, p) for p in odo.planes[0]))  # (Jacobians: the check)
    Q, _ = sandwich_inputs(cfg.smoothing, planes, rel, len(gt))
    assert Q is not None
    step = first_step_covariance(rel)
    print(f"world {args.world} noise {args.noise} epochs {len(gt)} statuses {odo.statuses[:4]}")
    for k in range(min(args.epochs, len(gt))):
        e, chi, n = nees_gauge.plane_deskew_error(odo.planes[k], full.poses[k], full.scene)
        models = {"motion": Q[k]}
        if k == 0 and step is not None:
            models |= {"step": step, "sum": Q[k] + step}
        txt = " ".join(f"{a} {v * 1e3:.3g}" for a, v in zip(AXES, e, strict=True))
        print(f" epoch {k}: {n} planes, e {txt} (mrad, mm)")
        for name, M in models.items():
            sig = np.sqrt(np.diag(M)) * 1e3
            chis = nees_where.plane_chis(odo.planes[k], full.poses[k], full.scene, M)
            txt = " ".join(f"{s:.3g}" for s in sig)
            fit = f"planes chi2 {chis[1]:.1f} (dof {chis[3]}; alone {chis[0]:.1f})"
            print(f"   {name:6s} sigma {txt}  {fit}")


if __name__ == "__main__":
    main()
