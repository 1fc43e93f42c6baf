"""The paper's section VI: Fig. 5 trajectories and Fig. 6 / 7 precision tables.

Runs :func:`planodom.experiments.paper.run_paper_experiment` (the library call behind
``planodom experiment paper``) and prints the tables. Run:
``uv run python experiments/paper_experiment.py [--out DIR] [--epochs N] [--motion M]``.
"""

from __future__ import annotations

import argparse
import time

from planodom.experiments.paper import (
    PAPER_METHODS,
    markdown_table,
    precision_markdown,
    run_paper_experiment,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results/paper")
    parser.add_argument("--epochs", type=int, default=None, help="default: one lap")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--motion", default="snapshot", choices=["snapshot", "continuous"])
    parser.add_argument("--methods", nargs="+", default=list(PAPER_METHODS))
    args = parser.parse_args()
    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", flush=True)

    result = run_paper_experiment(
        args.out, methods=args.methods, seed=args.seed, n_epochs=args.epochs,
        motion=args.motion, progress=progress,
    )  # fmt: skip
    print()
    print(precision_markdown(result.precision))
    print(markdown_table(result.summary))
    for name, path in result.files.items():
        print(f"{name}: {path}")


if __name__ == "__main__":
    main()
