"""Per-epoch trace of a lidar world: which epochs carry planodom's error (issue 11, LIDAR335).

``uv run python experiments/lidar_epoch_trace.py W NOISE [--epochs N] [--set KEY=VALUE ...]
[--cache DIR] [--tag NAME] [--out FILE.npz]``: the generalisation experiment's world ``W``
(odd: a lidar) at range noise NOISE (m), simulated once (with ``--cache`` kept as a pickle
for the next call), the oracle and planodom as the experiment runs it (the world's sweep
declared, the configuration with ``--set`` overrides); one line per step: status, the
registration stage, planes extracted, the step's signed roll / pitch / yaw error (0.001
deg) and its rotation and xy error against the oracle's; then the steps sorted by error
and the share of the squared rotation error in the worst 1 / 5 / 10 steps. With ``--out``
the per-step errors and poses are saved.
"""

from __future__ import annotations

import argparse
import os
import pickle
import time

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.oracle import run_oracle
from planodom.simulation.random_world import simulate_world, world_fields


def simulated(index: int, noise: float, epochs: int, cache: str | None):  # noqa: ANN201
    """(world, full simulation, fields as recorded, true poses from the first epoch)."""
    world = world_for(index)
    path = None if cache is None else os.path.join(cache, f"w{index}_{noise:g}_{epochs}.pkl")
    if path is not None and os.path.exists(path):
        with open(path, "rb") as f:
            full = pickle.load(f)
    else:
        full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
        if path is not None:
            os.makedirs(cache, exist_ok=True)  # type: ignore[arg-type]
            with open(path, "wb") as f:
                pickle.dump(full, f)
    data = world_fields(world, full)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    return world, full, data, gt


def signed(poses: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """(E - 1, 5) signed per-step errors: roll, pitch, yaw (deg), x, y (m)."""
    e = per_epoch_errors(relative_motions(poses), relative_motions(gt))
    return np.column_stack([np.degrees(e["roll"]), np.degrees(e["pitch"]),
                            np.degrees(e["yaw"]), e["x"], e["y"]])  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("world", type=int)
    p.add_argument("noise", type=float)
    p.add_argument("--epochs", type=int, default=150)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--cache")
    p.add_argument("--tag", default="run")
    p.add_argument("--no-oracle", action="store_true")
    p.add_argument("--quiet", action="store_true", help="no per-step lines")
    p.add_argument("--out")
    args = p.parse_args()
    world, full, data, gt = simulated(args.world, args.noise, args.epochs, args.cache)
    out: dict[str, np.ndarray] = {"gt": gt, "times": np.asarray(data.times)}
    oe = None
    if not args.no_oracle:
        orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
        oe = signed(orc.poses, gt)
        out["oracle"] = np.asarray(orc.poses)
    cfg = declared_sweep(world, PlanodomConfig())
    if args.set:
        import yaml

        pairs = (s.split("=", 1) for s in args.set)  # "off" / "on" stay words, not booleans
        changes = {k: v if v in ("off", "on") else yaml.safe_load(v) for k, v in pairs}
        cfg = cfg.updated(changes, source="lidar_epoch_trace")
    c0 = time.process_time()
    odo = run_odometry(data, cfg)
    cpu = time.process_time() - c0
    e = signed(odo.poses, gt)
    rot = np.linalg.norm(e[:, :3], axis=1)
    xy = np.hypot(e[:, 3], e[:, 4])
    a = ate(odo.poses, gt, align="origin", xy_only=True)["rmse"]
    head = f"world {args.world} {world.description['kind']} {world.description['family']}"
    if not args.quiet:
        print("step status stage planes | roll pitch yaw (0.001 deg) | rot xy(mm) | oracle rot")
        for k in range(len(rot)):
            r = odo.results[k + 1]
            stage = "" if r is None or r.diagnostics is None else r.diagnostics.pipeline
            orot = "" if oe is None else f"{1000 * np.linalg.norm(oe[k, :3]):.3f}"
            print(f"{k + 1:4d} {odo.statuses[k + 1]:>10} {stage:>18} {odo.n_planes[k + 1]:3d} | "
                  f"{1000 * e[k, 0]:+8.3f} {1000 * e[k, 1]:+8.3f} {1000 * e[k, 2]:+8.3f} | "
                  f"{1000 * rot[k]:8.3f} {1000 * xy[k]:7.3f} | {orot}")  # fmt: skip
    order = np.argsort(rot)[::-1]
    tot = float(np.sum(rot**2))
    shares = [float(np.sum(rot[order[:n]] ** 2) / tot) for n in (1, 5, 10)]
    rms = float(np.sqrt(np.mean(rot**2)))
    ox = "" if oe is None else f" ({rms / np.sqrt(np.mean(np.sum(oe[:, :3] ** 2, 1))):.1f}x oracle)"
    print(f"{head} {args.noise * 1000:g} mm {args.tag}: rot rms {1000 * rms:.3f}e-3 deg{ox}, "
          f"per axis {np.round(1000 * np.sqrt(np.mean(e[:, :3] ** 2, 0)), 3).tolist()}, "
          f"mean {np.round(1000 * e[:, :3].mean(0), 3).tolist()}; xy rms "
          f"{1000 * np.sqrt(np.mean(xy**2)):.3f} mm; ATE {1000 * a:.2f} mm; unresolved "
          f"{odo.n_unresolved}; CPU {cpu:.0f} s")  # fmt: skip
    print(f"  worst steps {(order[:10] + 1).tolist()}; share of squared rot in worst 1/5/10: "
          f"{np.round(shares, 2).tolist()}")  # fmt: skip
    out |= {"err": e, "poses": np.asarray(odo.poses), "n_planes": np.asarray(odo.n_planes)}
    out["status"] = np.array(odo.statuses)
    if oe is not None:
        out["oerr"] = oe
    if args.out:
        np.savez(args.out, **out)  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
