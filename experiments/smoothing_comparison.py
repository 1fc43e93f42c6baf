"""Odometry (delta = 1, delta = D) vs windowed and batch smoothing, four noise levels, two scenes.

Runs :func:`planodom.experiments.smoothing.run_smoothing_experiment` (the library call
behind ``planodom experiment smoothing``) and prints the tables. Run:
``uv run python experiments/smoothing_comparison.py [--out DIR] [--window W] [--delta D]``.
"""

from __future__ import annotations

import argparse
import time

from planodom.experiments.paper import PAPER_NOISE_LEVELS, markdown_table
from planodom.experiments.smoothing import SCENES, run_smoothing_experiment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results/smoothing")
    parser.add_argument("--window", type=int, default=10)
    parser.add_argument("--delta", type=int, default=3)
    parser.add_argument("--epochs", type=int, default=None, help="default: whole path")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--motion", default="snapshot", choices=["snapshot", "continuous"])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--noise", nargs="+", type=float, default=list(PAPER_NOISE_LEVELS))
    args = parser.parse_args()
    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", flush=True)

    result = run_smoothing_experiment(
        args.out, noise_levels=args.noise, scenes=args.scenes, window=args.window,
        delta=args.delta, seed=args.seed, n_epochs=args.epochs, motion=args.motion,
        progress=progress,
    )  # fmt: skip
    print()
    print(markdown_table(result.summary))
    print(markdown_table(result.nees))
    for name, path in result.files.items():
        print(f"{name}: {path}")


if __name__ == "__main__":
    main()
