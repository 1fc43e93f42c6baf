"""NEES of the odometry's relative poses, the extracted planes and the batch-smoothed poses.

Runs :func:`planodom.experiments.consistency.run_consistency_experiment` and prints three
tables per scene and noise level (seeds pooled): relative poses (5 DoF, per delta),
planes (3 DoF, TLS covariance and as the plane factor uses it), and smoothed poses
(x, y, roll, pitch, yaw: body z, unobserved by the odometry, is marginalised) for each
graph variant, each with the 95 % chi-square interval of its average. See that module's
docstring for the definitions. Run (about 2 minutes with the defaults, 2 scenes x 3
noise levels x 2 seeds x 150 epochs):

``uv run python experiments/smoothing_consistency.py [--scenes paper-loop urban-canyon]
[--noise 0.006 0.02 0.1] [--seeds 1 2 3] [--epochs 200]
[--variants graph all between planes] [--set smoothing.key=value ...]``

``--set`` overrides config fields, e.g. the behaviour before the consistency fixes:
``--set smoothing.between_factors=all smoothing.plane_confidence_scaling=true
smoothing.covariances_relative_to_first=false``.
"""

from __future__ import annotations

import argparse
import time

import yaml

from planodom.config import PlanodomConfig
from planodom.experiments.consistency import VARIANTS, run_consistency_experiment
from planodom.experiments.tables import markdown_table


def config_with(overrides: list[str]) -> PlanodomConfig:
    """Defaults with ``section.key=value`` overrides (values parsed as YAML)."""
    changes = {}
    for item in overrides:
        key, _, value = item.partition("=")
        changes[key] = yaml.safe_load(value)
    return PlanodomConfig().updated(changes, source="--set")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["paper-loop", "urban-canyon"])
    parser.add_argument("--noise", nargs="+", type=float, default=[0.006, 0.02, 0.1])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2])
    parser.add_argument("--epochs", type=int, default=150, help="0: the whole path")
    parser.add_argument("--delta", type=int, default=3)
    parser.add_argument("--variants", nargs="+", default=["graph"], choices=list(VARIANTS))
    parser.add_argument("--motion", default="snapshot", choices=["snapshot", "continuous"])
    parser.add_argument("--set", nargs="*", action="extend", default=[], dest="overrides")
    args = parser.parse_args()
    config = config_with([f"smoothing.delta_max={args.delta}", *args.overrides])
    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", flush=True)

    tables = run_consistency_experiment(
        args.scenes, args.noise, args.seeds, args.epochs or None, config, args.variants,
        args.motion, progress,
    )  # fmt: skip
    for name, rows in tables.items():
        print(f"\n{name}\n")
        print(markdown_table(rows))


if __name__ == "__main__":
    main()
