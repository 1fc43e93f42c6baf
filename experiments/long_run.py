"""Memory of a long run: resident set size while the odometry runs over 10 000 epochs.

One lap of the paper loop (730 epochs, isoclinal rig) is simulated and written as a
dataset once; the run then reads its scan files over and over (epoch k reads file
k mod 730: the lap repeated, a 6 cm jump where it closes), through the same path as
``planodom run``: the lazy :class:`planodom.datasets.Dataset`, the CLI's ``ScanEpochs``,
:func:`planodom.odometry.run_odometry` and a results folder written at the end. Only one
scan is in memory at a time; what grows with the epochs is what the run keeps per epoch
(poses, relative-pose results and planes, which the smoother needs).

Prints the RSS every ``--every`` epochs and the peak. Not a timed test; run by hand:
``uv run python experiments/long_run.py [--epochs 10000] [--every 500]``.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from planodom.cli.common import ScanEpochs
from planodom.config import PlanodomConfig
from planodom.datasets import Dataset
from planodom.odometry import run_odometry
from planodom.results import odometry_metrics, results_folder, write_odometry_run
from planodom.simulation import simulate_named
from planodom.simulation.export import write_simulated_dataset


def rss_mb() -> float:
    """Current resident set size (MB), from /proc/self/statm."""
    pages = int(Path("/proc/self/statm").read_text().split()[1])
    return pages * resource.getpagesize() / 2**20


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def looped_dataset(root: Path, n_epochs: int, noise: float) -> Dataset:
    """A dataset of ``n_epochs`` epochs reading one simulated lap's files in a loop."""
    lap = write_simulated_dataset(
        simulate_named("paper-loop", "isoclinal", noise=noise, seed=1, motion="snapshot"),
        root / "lap",
        "paper-loop",
    )
    files = [lap.scan_files[k % len(lap)] for k in range(n_epochs)]
    return Dataset(root / "lap", files, np.arange(n_epochs) * 0.1, None, lap.rig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--epochs", type=int, default=10_000)
    parser.add_argument("--every", type=int, default=500)
    parser.add_argument("--noise", type=float, default=0.006)
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        data = ScanEpochs(looped_dataset(Path(tmp), args.epochs, args.noise))
        print(f"dataset ready: {len(data)} epochs; RSS {rss_mb():.0f} MB")
        start = time.perf_counter()
        samples: list[tuple[int, float, float]] = []

        def progress(k: int, n: int) -> None:
            if k == 1 or k % args.every == 0 or k == n:
                samples.append((k, rss_mb(), time.perf_counter() - start))
                print(f"epoch {k:6d}  RSS {samples[-1][1]:7.1f} MB  {samples[-1][2]:7.1f} s")

        run = run_odometry(data, PlanodomConfig(), progress=data.progress(progress))
        with results_folder(Path(tmp) / "results") as folder:
            write_odometry_run(folder.tmp, run, odometry_metrics(run, None))
        print(f"results written; RSS {rss_mb():.1f} MB, peak {peak_mb():.1f} MB")

    k, mb, _ = np.array(samples).T
    half = k >= k[-1] / 2
    slope = np.polyfit(k[half], mb[half], 1)[0] * 1000
    print(
        f"{args.epochs} epochs in {samples[-1][2]:.0f} s; RSS {mb[0]:.0f} MB after epoch 1, "
        f"{mb[-1]:.0f} MB at the end, peak {peak_mb():.0f} MB; second half: "
        f"{slope:.2f} MB per 1000 epochs ({slope:.2f} kB per epoch kept)"
    )


if __name__ == "__main__":
    main()
