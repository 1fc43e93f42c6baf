"""Issue 14's targets on 2D-rig laps, one row per lap (LOOPNEES): the odometry, the oracle and
the batch with loops side by side, with the smoothed poses' NEES.

Per world and range noise, the lap and its odometry as ``nees_gauge.load`` (``planodom smooth``'s
odometry, cached with ``--cache DIR``), the oracle's pure odometry on the same scans
(:func:`planodom.oracle.run_oracle`), and the batch with loops (default covariances) once with
the default config and, with ``--set`` (repeatable), once more per set of overrides on the same
odometry.
Per row: epochs, unresolved odometry epochs, odometry / oracle / batch ATE (xy rmse,
origin-aligned, m), the batch's xy error at the loop's end (m), mean NEES5 of the smoothed
poses (chi2(5) 95 % interval for a lap's mean: [0.83, 12.8]), loop factors kept and wrong
(``loop_factor_counts``: a component off by more than 3 of its sigmas), their largest
horizontal truth error (cm), plane ties kept and wrong (``reidentification_counts``), and the
batch's process time (s, covariances included), wall time and its child processes' CPU time.
Per epoch (``--npz DIR``): the pose errors, covariances and the epochs' odometry status, for
``nees_where``-style tracing.

    uv run python experiments/lap_targets.py --worlds 360,362 --noise 0.006 0.02 \\
        --cache DIR --out FILE.csv [--set '{"smoothing.KEY": VALUE}'] [--npz DIR] \\
        [--odometry-set '{"odometry.KEY": VALUE}']
"""

from __future__ import annotations

import argparse
import csv
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402

from planodom.experiments.loops import coplanar  # noqa: E402
from planodom.geometry import invert_transform  # noqa: E402
from planodom.metrics import ate, errors_nees, pose_errors  # noqa: E402
from planodom.oracle import run_oracle  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.loop_records import (  # noqa: E402
    loop_factor_counts,
    reidentification_counts,
)


def _ate(poses: np.ndarray, gt: np.ndarray) -> float:
    return float(ate(poses, gt, xy_only=True)["rmse"])


def _children_cpu() -> float:
    """CPU time of this process's ended children, s (``batch_initial_concurrent``'s)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def lap_rows(world_index: int, noise: float, settings: list[dict], cache: Path | None,
             npz: Path | None, odometry: dict | None = None) -> list[dict]:  # fmt: skip
    """One row per setting on one lap (the odometry, with the config changes ``odometry``,
    and the oracle shared)."""
    world, full, cfg, odo, rel = nees_gauge.load(world_index, noise, cache, odometry)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    oracle = run_oracle(full.scans, full.times, world.trajectory, world.scene)
    common = {
        "world": world_index, "noise_m": noise, "odometry": json.dumps(odometry or {}),
        "epochs": len(gt),
        "unresolved": odo.statuses.count("unresolved"),
        "odometry_ate_m": _ate(odo.poses, gt), "oracle_ate_m": _ate(oracle.poses, gt),
    }  # fmt: skip
    rows = []
    for i, changes in enumerate(settings):
        start, wall, child = time.process_time(), time.perf_counter(), _children_cpu()
        res = smooth_batch(odo.planes, rel, cfg.updated(changes))
        cpu, wall = time.process_time() - start, time.perf_counter() - wall
        child = _children_cpu() - child
        xi = pose_errors(res.poses, gt)
        nees = (
            np.full(len(gt) - 1, np.nan)
            if res.covariances is None
            else errors_nees(xi[1:], res.covariances[1:], range(5))
        )
        rows.append({
            **common, "setting": json.dumps(changes), "ate_m": _ate(res.poses, gt),
            "loop_end_m": float(np.linalg.norm(res.poses[-1][:2, 3] - gt[-1][:2, 3])),
            "mean_nees5": float(np.nanmean(nees)), "covariance_model": res.covariance_model,
            **loop_factor_counts(res.loop_factors, gt),
            **reidentification_counts(res.reidentifications, coplanar(world.scene)),
            "batch_cpu_s": cpu, "batch_wall_s": wall, "batch_children_cpu_s": child,
            # batch_initial "checked": worst chi2 of the windowed guess, its span, replaced
            "initial_check": "" if res.initial_check is None else json.dumps(res.initial_check),
        })  # fmt: skip
        if npz is not None:
            tag = "default" if i == 0 else "option" if i == 1 else f"option{i}"
            np.savez_compressed(
                npz / f"lap_w{world_index}_{noise}_{tag}.npz", xi=xi, nees5=nees,
                P=res.covariances if res.covariances is not None else np.zeros(0),
                statuses=np.array(odo.statuses),
            )  # fmt: skip
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", required=True, help="comma-separated world indices (even)")
    parser.add_argument("--noise", type=float, nargs="+", required=True)
    parser.add_argument(
        "--set", action="append", default=[], help="JSON config changes (another batch; repeatable)"
    )
    parser.add_argument(
        "--odometry-set",
        default=None,
        help="JSON config changes of the odometry (every batch on it)",
    )
    parser.add_argument("--cache", type=Path, default=None)
    parser.add_argument("--npz", type=Path, default=None)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    settings = [{}] + [json.loads(changes) for changes in args.set]
    rows: list[dict] = []
    for w in (int(x) for x in args.worlds.split(",")):
        for noise in args.noise:
            odometry = json.loads(args.odometry_set) if args.odometry_set else None
            rows += lap_rows(w, noise, settings, args.cache, args.npz, odometry)
            for r in rows[-len(settings) :]:
                print(json.dumps(r), flush=True)
            keys = list(dict.fromkeys(k for r in rows for k in r))
            with args.out.open("w", newline="") as f:  # the rows so far
                out = csv.DictWriter(f, fieldnames=keys)
                out.writeheader()
                out.writerows(rows)


if __name__ == "__main__":
    main()
