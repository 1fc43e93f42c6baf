"""A smoothing option against the default on laps' batch with loops, on the same odometry
(issue 14, W32D): per world, noise and setting one row of ATE (xy rmse), the loop end's
horizontal error, the plane ties kept and wrong (``reidentification_counts``) and the loop
factors kept and wrong (``loop_factor_counts``: a component off the truth by more than 3 of
its sigmas), and the largest horizontal truth error of a kept loop factor.

The odometry is ``nees_gauge.load``'s (as ``planodom smooth`` and ``planodom experiment
loops`` run it), cached in ``--cache DIR``; the batch runs without covariances (they move
no pose).

    uv run python experiments/loop_option_laps.py --worlds 280,282 --noise 0.006 \\
        --set '{"smoothing.loop_candidate_reference": "spanning"}' --cache DIR --out FILE.csv
    uv run python experiments/loop_option_laps.py --summarise FILE.csv ...
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402

from planodom.experiments.loops import coplanar  # noqa: E402
from planodom.geometry import invert_transform  # noqa: E402
from planodom.metrics import ate  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.loop_records import (  # noqa: E402
    loop_factor_counts,
    reidentification_counts,
)


def lap_row(world_index: int, noise: float, changes: dict, cache: Path | None) -> dict:
    """One lap's batch with loops under ``changes`` (on the default odometry)."""
    world, full, cfg, odo, rel = nees_gauge.load(world_index, noise, cache)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    run = cfg.updated({"smoothing.compute_covariances": False, **changes})
    res = smooth_batch(odo.planes, rel, run)
    kept = [f for f in res.loop_factors if not f.removed]
    worst = max((float(np.linalg.norm(f.truth_error(gt)[3:])) for f in kept), default=0.0)
    return {
        "world": world_index, "noise_m": noise, "setting": json.dumps(changes),
        "ate_m": ate(res.poses, gt, xy_only=True)["rmse"],
        "loop_end_m": float(np.linalg.norm(res.poses[-1][:2, 3] - gt[-1][:2, 3])),
        **reidentification_counts(res.reidentifications, coplanar(world.scene)),
        **loop_factor_counts(res.loop_factors, gt),
        "kept_factor_max_error_m": worst,
    }  # fmt: skip


def summarise(paths: list[Path]) -> None:
    """Per noise: the option's rows against the default's (the rule's figures, W32D)."""
    rows = [r for p in paths for r in csv.DictReader(p.open())]
    for noise in sorted({r["noise_m"] for r in rows}):
        pairs: dict[str, dict[str, dict]] = {}
        for r in rows:
            if r["noise_m"] == noise:
                pairs.setdefault(r["world"], {})[
                    "default" if r["setting"] == "{}" else "option"
                ] = r
        both = {w: p for w, p in pairs.items() if len(p) == 2}
        ratios = [float(p["option"]["ate_m"]) / float(p["default"]["ate_m"]) for p in both.values()]
        print(f"noise {noise}: {len(both)} laps, ATE geometric-mean ratio "
              f"{float(np.exp(np.mean(np.log(ratios)))):.4f}")  # fmt: skip
        for key in ("wrong_kept", "loop_factors", "loop_factors_wrong_kept"):
            sums = [sum(int(p[s][key]) for p in both.values()) for s in ("default", "option")]
            print(f"  {key}: {sums[0]} -> {sums[1]}")
        under = [
            sum(float(p[s]["loop_end_m"]) < 0.1 for p in both.values())
            for s in ("default", "option")
        ]
        print(f"  loop ends under 10 cm: {under[0]} -> {under[1]}")
        for w, p in sorted(both.items(), key=lambda x: int(x[0])):
            d, o = p["default"], p["option"]
            print(
                f"  world {w}: ATE {float(d['ate_m']):.4f} -> {float(o['ate_m']):.4f} m, loop end "
                f"{float(d['loop_end_m']) * 100:.2f} -> {float(o['loop_end_m']) * 100:.2f} cm, "
                f"loop factors kept {d['loop_factors']} -> {o['loop_factors']} (wrong "
                f"{d['loop_factors_wrong_kept']} -> {o['loop_factors_wrong_kept']}, worst "
                f"{float(d['kept_factor_max_error_m']):.2f} -> "
                f"{float(o['kept_factor_max_error_m']):.2f} m), wrong ties "
                f"{d['wrong_kept']} -> {o['wrong_kept']}"
            )


def main() -> None:
    if sys.argv[1:2] == ["--summarise"]:
        summarise([Path(p) for p in sys.argv[2:]])
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", required=True, help="comma-separated world indices")
    parser.add_argument("--noise", type=float, nargs="+", required=True)
    parser.add_argument("--set", default="{}", help="JSON config changes (the option)")
    parser.add_argument("--cache", type=Path, default=None)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    settings = [{}, json.loads(args.set)]
    rows: list[dict] = []
    for w in (int(x) for x in args.worlds.split(",")):
        for noise in args.noise:
            for changes in settings:
                rows.append(lap_row(w, noise, changes, args.cache))
                print(json.dumps(rows[-1]), flush=True)
                with args.out.open("w", newline="") as f:  # the rows so far
                    out = csv.DictWriter(f, fieldnames=list(rows[0]))
                    out.writeheader()
                    out.writerows(rows)


if __name__ == "__main__":
    main()
