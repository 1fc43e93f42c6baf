"""Smoothing benchmarks: batch over a long sequence, windowed epochs per second.

Targets (issue 5): batch smoothing of 2 000 epochs in under 30 s; the windowed smoother
at 100 epochs per second or more on the default loop with W = 10, D = 3. The inputs
(planes and relative poses) are prepared first and not timed: these time the smoothers.

- ``synthetic``: :func:`planodom.smoothing.synthetic.make_sequence` (walls and ground along
  a wandering path, Gaussian noise that matches the noise models), ``--epochs`` long;
- ``loop``: the default paper loop simulated with the isoclinal rig at 6 mm, planes
  extracted and relative poses estimated for delta = 1..D (``--no-loop`` skips it).

Run: ``uv run python experiments/bench_smoothing.py [--epochs 2000] [--no-loop]``.
"""

from __future__ import annotations

import argparse
import time

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.metrics import summarize
from planodom.smoothing import smooth_batch, smooth_windowed
from planodom.smoothing.synthetic import make_sequence


def bench(name: str, planes, relatives, gt, config: SmoothingConfig) -> list[dict[str, object]]:
    rows = []
    for mode, smooth in (("batch", smooth_batch), ("windowed", smooth_windowed)):
        result = smooth(planes, relatives, config)
        rows.append(
            {
                "input": name,
                "mode": mode,
                "epochs": len(planes),
                "seconds": result.runtime_s,
                "epochs_per_s": len(planes) / result.runtime_s,
                "iterations": len(result.errors) - 1 if result.errors else 0,
                "landmarks": len(result.landmarks),
                "plane_factors": result.stats.plane_factors,
                "ate_rmse_m": summarize(result.poses, gt)["ate_rmse_m"],
                "covariances": result.covariances is not None,
            }
        )
    return rows


def loop_inputs(config: PlanodomConfig, noise: float, seed: int):
    from planodom.extraction import extract_planes
    from planodom.geometry import invert_transform
    from planodom.odometry import run_odometry
    from planodom.simulation import simulate_named
    from planodom.smoothing.run import relative_poses

    sim = simulate_named("paper-loop", "isoclinal", noise=noise, seed=seed, motion="snapshot")
    planes = [extract_planes(scan, config.extraction) for scan in sim]
    odo = run_odometry(planes, config, times=sim.times.tolist())
    D = config.smoothing.delta_max
    relatives = relative_poses(planes, config, range(1, D + 1), odo.poses)
    return planes, relatives, invert_transform(sim.poses[0])[None] @ sim.poses


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--epochs", type=int, default=2000)
    parser.add_argument("--window", type=int, default=10)
    parser.add_argument("--delta", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-loop", action="store_true")
    args = parser.parse_args()
    config = PlanodomConfig.from_dict(
        {"smoothing": {"window": args.window, "delta_max": args.delta}}
    )
    rows = []
    t0 = time.perf_counter()
    seq = make_sequence(
        args.epochs, args.seed, delta_max=args.delta, sigma_rotation=1e-3,
        sigma_translation=0.01, sigma_normal=0.005, sigma_offset=0.01,
    )  # fmt: skip
    print(f"synthetic input: {args.epochs} epochs in {time.perf_counter() - t0:.1f} s", flush=True)
    rows += bench("synthetic", seq.planes, seq.relatives, seq.poses, config.smoothing)
    if not args.no_loop:
        t0 = time.perf_counter()
        planes, relatives, gt = loop_inputs(config, 0.006, args.seed)
        print(f"paper loop input: {len(planes)} epochs in {time.perf_counter() - t0:.1f} s")
        rows += bench("paper-loop 6 mm", planes, relatives, gt, config.smoothing)
    from planodom.experiments.tables import markdown_table

    print(markdown_table(rows))


if __name__ == "__main__":
    main()
