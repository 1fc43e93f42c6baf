"""A variant of ``planodom experiment generalisation`` against a base, world by world.

Reads the ``runs.csv`` of each (several folders each, e.g. ``--first-world 180`` and
``20``), pairs the rows by world, noise and method, and prints per noise: the geometric
means of the per-world ratios variant / base of the ATE and the per-epoch rotation and
xy rms, with the worlds better and worse by more than 1 %, the worst ratio (world), the
summed unresolved and degenerate epochs of each, and the worlds whose ATE is worse by
more than 2x and 0.1 m (the clauses of DESKEWCOV's rule, docs/RESULTS.md); one line per noise
and method.

    uv run python experiments/runs_ratio.py --base B180 B20 --variant V180 V20
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

METRICS = {"ATE": "ate_xy_m", "rotation": "rot_rms_deg", "xy": "xy_rms_m"}


def read_runs(folders: list[str]) -> dict[tuple[int, float, str], dict[str, str]]:
    """(world, noise, method) -> row of every ``runs.csv`` in ``folders``."""
    rows = {}
    for folder in folders:
        with open(Path(folder) / "runs.csv", newline="") as f:
            for row in csv.DictReader(f):
                rows[(int(row["world"]), float(row["noise_m"]), row["method"])] = row
    return rows


def compare(base: dict, variant: dict) -> list[str]:
    """The lines of the comparison (module docstring)."""
    keys = sorted(set(base) & set(variant))
    lines = []
    # One line per noise and method: pooling the methods would count the oracle's rows
    # (equal in both runs, ratio 1) into the means and pull them towards 1.
    for noise, method in sorted({(k[1], k[2]) for k in keys}):
        ks = [k for k in keys if k[1] == noise and k[2] == method]
        parts = [f"{noise * 1000:g} mm, {method}, {len(ks)} worlds"]
        for name, col in METRICS.items():
            r = np.array([float(variant[k][col]) / float(base[k][col]) for k in ks])
            worst = int(np.argmax(r))
            parts.append(
                f"{name} {np.exp(np.mean(np.log(r))):.3f} ({int(np.sum(r < 0.99))} better / "
                f"{int(np.sum(r > 1.01))} worse, worst {r[worst]:.2f} world {ks[worst][0]})"
            )
        for col in ("unresolved", "degenerate"):
            total = [sum(float(d[k][col]) for k in ks) for d in (base, variant)]
            parts.append(f"{col} {total[0]:g} -> {total[1]:g}")
        bad = [
            f"{k[0]} {float(base[k]['ate_xy_m']):.3f} -> {float(variant[k]['ate_xy_m']):.3f}"
            for k in ks
            if float(variant[k]["ate_xy_m"]) > 2 * float(base[k]["ate_xy_m"])
            and float(variant[k]["ate_xy_m"]) - float(base[k]["ate_xy_m"]) > 0.1
        ]
        parts.append("worse by > 2x and 0.1 m: " + (", ".join(bad) or "none"))
        lines.append("; ".join(parts))
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", nargs="+", required=True, help="folders with runs.csv")
    parser.add_argument("--variant", nargs="+", required=True, help="folders with runs.csv")
    args = parser.parse_args()
    for line in compare(read_runs(args.base), read_runs(args.variant)):
        print(line)


if __name__ == "__main__":
    main()
