"""How many walls does the default rig observe as planes on the paper loop?

For each epoch of one lap of the default paper loop with the default isoclinal rig (noise
free, continuous motion), counts the walls hit, the walls observable as planes (two
traces, i.e. two rings, with directions more than 10 deg apart; see the brief's RIG.md
and :mod:`planodom.simulation.observability`) and the pairs of observable walls with
non-parallel normals, which is what the rotation and translation of the paper need (at
least one pair per epoch). Prints min / median / max, a histogram and the fraction of
epochs with at least one pair.

``--compare`` also evaluates alternative geometries: both pairs meeting along the same
direction (the forward axis, like two rolled scanners; or the lateral axis, like two
nodding ones), and the default meeting directions with other inclinations.
``--plot PATH`` saves the per-epoch counts along the loop as a PNG.

Run: ``uv run python experiments/observability.py [--compare] [--plot obs.png]``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

from planodom.simulation import (
    ObservabilityStats,
    SensorRig,
    Simulator,
    isoclinal_rig,
    observability,
    paper_loop,
    paper_loop_trajectory,
)


def evaluate(rig: SensorRig, stride: int = 1, min_angle_deg: float = 10.0) -> ObservabilityStats:
    """Observability of every ``stride``-th 10 Hz epoch of one noise-free lap of the paper
    loop with ``rig``; traces count as crossing above ``min_angle_deg``."""
    scene, trajectory = paper_loop(), paper_loop_trajectory()
    sim = Simulator(scene, trajectory, rig)
    n = int(trajectory.duration * sim.epoch_rate)
    scans = [sim.epoch(k, k / sim.epoch_rate).scan for k in range(0, n, stride)]
    return observability(scans, scene, min_angle_deg=min_angle_deg)


def report(name: str, stats: ObservabilityStats) -> None:
    s = stats.summary()
    fmt = "/".join
    print(
        f"{name:<34} hit {fmt(f'{v:g}' for v in s['walls_hit']):>9}  "
        f"observable {fmt(f'{v:g}' for v in s['walls_observable']):>8}  "
        f"pairs {fmt(f'{v:g}' for v in s['pairs']):>9}  "
        f">=1 pair {np.mean(stats.pairs >= 1):6.1%}  ground {np.mean(stats.ground):6.1%}"
    )


def histogram(stats: ObservabilityStats) -> None:
    counts = np.bincount(stats.walls_observable)
    print("\nwalls observable as planes per epoch (histogram):")
    for k, c in enumerate(counts):
        print(f"  {k:2d} | {'#' * int(np.ceil(60 * c / counts.max())):<60} {c}")


ALTERNATIVES: dict[str, Callable[[], SensorRig]] = {
    "both pairs meet forward (0/0)": lambda: isoclinal_rig(meet_deg=(0, 0)),
    "both pairs meet lateral (90/90)": lambda: isoclinal_rig(meet_deg=(90, 90)),
    "meet 0 / 90": lambda: isoclinal_rig(meet_deg=(0, 90)),
    "meet +60/-60": lambda: isoclinal_rig(meet_deg=(60, -60)),
    "meet +45/-45, inclination 15": lambda: isoclinal_rig(inclination_deg=15),
    "meet +45/-45, inclination 35": lambda: isoclinal_rig(inclination_deg=35),
}


def plot(stats: ObservabilityStats, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 4))
    t = np.arange(len(stats.walls_hit)) / 10.0
    ax.plot(t, stats.walls_hit, label="walls hit")
    ax.plot(t, stats.walls_observable, label="walls observable as planes")
    ax.plot(t, stats.pairs, label="non-parallel pairs of observable walls")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("count per epoch")
    ax.set_title("Paper loop, default isoclinal rig")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--compare", action="store_true", help="also try other geometries")
    parser.add_argument("--plot", metavar="PATH", help="save a PNG of the per-epoch counts")
    parser.add_argument(
        "--min-angle",
        type=float,
        default=10.0,
        help="traces cross above this angle, degrees (default 10)",
    )
    args = parser.parse_args()
    print(
        f"paper loop, one lap at 2 m/s, 10 Hz epochs, traces crossing > {args.min_angle:g} deg;"
        " min/median/max per epoch"
    )
    stats = evaluate(isoclinal_rig(), min_angle_deg=args.min_angle)
    report("default: meet +45/-45, incl. 25", stats)
    if args.compare:
        print("alternatives (every 4th epoch):")
        for name, make in ALTERNATIVES.items():
            report(name, evaluate(make(), stride=4, min_angle_deg=args.min_angle))
    histogram(stats)
    if args.plot:
        plot(stats, args.plot)
        print(f"\nplot saved to {args.plot}")


if __name__ == "__main__":
    main()
