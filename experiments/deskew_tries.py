"""Every extraction the deskewing policy tried at chosen epochs of a built-in scene (issue 11,
SIGMA0B).

Runs the odometry as ``planodom run --scenario`` does (``--set`` overrides) and, at each
epoch of ``--epochs-at``, prints every extraction :func:`planodom.odometry.deskew.
register_deskewed` asked for, in order: the twist (roll, pitch, yaw rates, deg/s /
speed, m/s; ``none``: not deskewed), whether it was refined from an estimate's own
twist, the status, the plane count, the true surfaces (``truth_id``) and distinct
surfaces, the step's yaw error against the truth (mdeg), its own yaw rate and
``twist_offset``'s share (deg/s); then what was committed against the true twist.

    uv run python experiments/deskew_tries.py --scene random-outdoor --noise 0 \\
        --epochs-at 240 515 584
"""

from __future__ import annotations

import argparse

import numpy as np
from builtin_scenes import config_with, simulated, true_twist

from planodom.metrics import relative_motions
from planodom.odometry.odometry import PlaneOdometry
from planodom.odometry.run import run_odometry
from planodom.odometry.surfaces import distinct_surfaces


def yaw_deg(T: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(T[1, 0], T[0, 0])))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="random-outdoor")
    ap.add_argument("--noise", default="0")
    ap.add_argument("--epochs-at", type=int, nargs="+", required=True)
    ap.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    args = ap.parse_args()
    sim, gt = simulated(args.scene, args.noise)
    n = max(args.epochs_at) + 1
    cfg, true_steps = config_with(args.set), relative_motions(gt[:n])
    tol = (cfg.association.normal_tol_deg, cfg.association.offset_tol_m)
    original, log = PlaneOdometry._estimate_scan, dict[int, list[str]]()

    def traced(self, scan, t, twist, source=None, prior_sigma=None):  # noqa: ANN001, ANN202
        e = original(self, scan, t, twist, source, prior_sigma)
        k = len(self.poses)
        if k in args.epochs_at:
            own, off = e.own_twist(t - self.times[-1]), e.twist_offset
            used = "none"
            if twist is not None:
                rates = ",".join(f"{r:+.3f}" for r in np.degrees(twist[:3]))
                used = f"{rates}/{np.linalg.norm(twist[3:]):.3f}"
            log.setdefault(k, []).append(
                f"  {used:>26s} {'refined' if source is not None else 'first  '} "
                f"{e.relative.status.name:10s} planes {len(e.planes):2d} "
                f"ids {[p.truth_id for p in e.planes]} "
                f"surfaces {distinct_surfaces(e.planes, *tol)} "
                f"step yaw {(yaw_deg(e.step) - yaw_deg(true_steps[k - 1])) * 1e3:+8.2f} mdeg "
                f"own {np.degrees(own[2]):+.3f} offset "
                f"{np.degrees(off[2]) if off is not None else float('nan'):+.3f} deg/s"
            )  # fmt: skip
        return e

    PlaneOdometry._estimate_scan = traced  # type: ignore[method-assign]
    try:
        run = run_odometry(list(sim.scans[:n]), cfg, sim.rig, times=sim.times[:n])
    finally:
        PlaneOdometry._estimate_scan = original  # type: ignore[method-assign]
    steps = relative_motions(run.poses)
    err = lambda k: (yaw_deg(steps[k - 1]) - yaw_deg(true_steps[k - 1])) * 1e3  # noqa: E731
    for k in args.epochs_at:
        used, true = run.results[k].deskew_twist, true_twist(sim, k)
        print(f"epoch {k}: {run.statuses[k]}, deskewed with "
              f"{'none' if used is None else np.round(np.degrees(used[:3]), 3)} deg/s (true "
              f"{np.round(np.degrees(true[:3]), 3)}), step yaw "
              f"{err(k):+.2f} mdeg")  # fmt: skip
        print("\n".join(log.get(k, [])))


if __name__ == "__main__":
    main()
