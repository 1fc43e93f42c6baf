"""The first epochs of the 2D-rig worlds against the truth (issues 11 and 14).

Per world and range noise: the odometry as ``planodom experiment generalisation`` runs it
(default config, ``--epochs`` epochs), and printed as one CSV row: the statuses of epochs
1-5, which of epochs 0-5 were kept without deskewing, the planes' error against their
true surfaces for epochs 0-2 (median angle mrad, median |offset| cm), the poses' error
of epochs 1-5 (mean rotation mrad, mean translation cm; the first pose is the frame), the
run's rotation / xy rms of the steps (deg, m), ATE xy (m, aligned at the origin) and
unresolved epochs.

    uv run python experiments/first_epochs.py --worlds 0 2 18 --noise 0.006 0.02 -o OUT.csv
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform, transform_planes
from planodom.metrics import ate, per_epoch_errors, pose_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields


def plane_errors(planes, T_world_base: np.ndarray, scene) -> tuple[float, float]:  # noqa: ANN001
    """Median angle (mrad) and |offset| (cm) of ``planes`` against their true surfaces."""
    n_w, d_w = transform_planes(invert_transform(T_world_base), scene.normals, scene.offsets)
    ids = {int(i): j for j, i in enumerate(scene.ids)}
    ang, off = [], []
    for p in planes:
        j = ids.get(int(p.truth_id))
        if j is None:
            continue
        n, d = n_w[j], float(d_w[j])
        if p.normal @ n < 0:
            n, d = -n, -d
        ang.append(np.arccos(np.clip(p.normal @ n, -1, 1)) * 1e3)
        off.append(abs(p.offset - d) * 100)
    return (float(np.median(ang)), float(np.median(off))) if ang else (np.nan, np.nan)


def row(world_index: int, noise: float, epochs: int, config: PlanodomConfig) -> dict:
    world = world_for(world_index)
    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    c0 = time.process_time()
    odo = run_odometry(world_fields(world, full), config)
    cpu = time.process_time() - c0
    gt = invert_transform(full.poses[0])[None] @ full.poses
    xi = pose_errors(odo.poses, gt)
    err = per_epoch_errors(relative_motions(odo.poses), relative_motions(gt))
    rot = np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))
    xy = np.hypot(err["x"], err["y"])
    kept = [k for k, r in enumerate(odo.results[1:6], 1) if r and r.deskew_twist is None]
    out = {
        "world": world_index, "noise": noise,
        "status1_5": " ".join(s[:3] for s in odo.statuses[1:6]),
        "undeskewed1_5": " ".join(map(str, kept)),
        "first5_rot_mrad": float(np.mean(np.linalg.norm(xi[1:6, :3], axis=1)) * 1e3),
        "first5_trans_cm": float(np.mean(np.linalg.norm(xi[1:6, 3:], axis=1)) * 100),
    }  # fmt: skip
    for k in range(3):
        a, o = plane_errors(odo.planes[k], full.poses[k], full.scene)
        out[f"planes{k}_mrad"], out[f"planes{k}_cm"] = a, o
    return out | {
        "rot_rms_deg": float(np.sqrt(np.mean(rot**2))),
        "xy_rms_m": float(np.sqrt(np.mean(xy**2))),
        "ate_xy_m": ate(odo.poses, gt, align="origin", xy_only=True)["rmse"],
        "unresolved": odo.n_unresolved,
        "cpu_s": cpu,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, nargs="+", required=True)
    parser.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    parser.add_argument("--epochs", type=int, default=150)
    parser.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    parser.add_argument("-o", "--out", type=Path, default=None)
    args = parser.parse_args()
    changes = {}
    for item in args.set:
        key, value = item.split("=", 1)
        changes[key] = int(value) if value.isdigit() else value
    config = PlanodomConfig().updated(changes, source="cli") if changes else PlanodomConfig()
    rows = []
    for noise in args.noise:
        for w in args.worlds:
            rows.append(row(w, noise, args.epochs, config))
            print({k: round(v, 4) if isinstance(v, float) else v for k, v in rows[-1].items()},
                  flush=True)  # fmt: skip
    stream = sys.stdout if args.out is None else args.out.open("w", newline="")
    writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)


if __name__ == "__main__":
    main()
