"""Where ``planemap.few_inliers: observed`` acts: the generalisation runs with a count (LIDAR335).

``uv run python experiments/few_inliers_acts.py --worlds 341 343 ... --noise 0.006 0.02
--out DIR [--set KEY=VALUE ...]``: planodom as ``planodom experiment generalisation
--methods planodom --epochs 150`` runs it (:func:`planodom.experiments.generalisation.
run_world`, the same simulation and configuration), with ``planemap.few_inliers:
observed`` and the overrides, writing ``DIR/runs.csv`` (the experiment's columns, for
``experiments/runs_ratio.py``) and ``DIR/acts.csv``: per world and noise, how many
registrations the rule resolved that the count of ``min_inliers`` would have left
unresolved (:func:`planodom.odometry.planemap.few_inliers.observed_few` returning True).
Where that count is 0, every registration was judged as without the option, so the run
equals the default's bit for bit: its ratio to the base is exactly 1 without running it.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import yaml

import planodom.odometry.planemap.odometry as pm_odometry
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import run_rows, run_world, world_for

_acts = [0]
_observed_few = pm_odometry.observed_few


def _counted(H, n_inliers, config):  # noqa: ANN001, ANN202
    ok = _observed_few(H, n_inliers, config)
    _acts[0] += bool(ok)
    return ok


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--worlds", type=int, nargs="+", required=True)
    p.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    p.add_argument("--epochs", type=int, default=150)
    p.add_argument("--set", nargs="*", action="extend", default=[])
    p.add_argument("--out", required=True)
    args = p.parse_args()
    pairs = (s.split("=", 1) for s in args.set)  # "off" / "on" stay words
    changes = {k: v if v in ("off", "on") else yaml.safe_load(v) for k, v in pairs}
    cfg = PlanodomConfig().updated({"planemap.few_inliers": "observed", **changes}, "acts")
    pm_odometry.observed_few = _counted  # the name the odometry calls
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows, acts = [], []
    for w in args.worlds:
        world = world_for(w)
        for noise in args.noise:
            _acts[0] = 0
            runs = run_world(world, noise, args.epochs, cfg, ["planodom"], print)
            rows += run_rows(runs)
            acts.append({"world": w, "noise_m": noise, "acted": _acts[0]})
            print(f"world {w} noise {noise}: the rule resolved {_acts[0]} registrations",
                  flush=True)  # fmt: skip
            for name, table in (("runs", rows), ("acts", acts)):
                with open(out / f"{name}.csv", "w", newline="") as f:
                    writer = csv.DictWriter(f, fieldnames=list(table[0]))
                    writer.writeheader()
                    writer.writerows(table)


if __name__ == "__main__":
    main()
