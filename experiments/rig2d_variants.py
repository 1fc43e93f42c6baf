"""Configuration variants of planodom on the same simulated 2D-rig runs (issue 11).

Each world and range noise is simulated once (as ``planodom experiment generalisation``
does, continuous motion, the world's fields) and given to ``run_odometry`` under every
variant: a name and config overrides (dotted ``KEY=VALUE``, YAML values). Per variant:
the per-epoch rotation and xy rms, the ATE (xy, origin-aligned; as
``experiments/rig2d_ingredients.py``'s ``metrics``), the unresolved epochs and the
process time of ``run_odometry`` (CPU, not wall: the machine is shared). With
``--oracle CSV`` (the rows of ``rig2d_ingredients.py`` on the same worlds and noises)
each figure is also given as a ratio to the oracle's. With ``--gaps`` the oracle
(:func:`planodom.oracle.run_oracle`) is run on each simulated run too, and each row gets
``gap`` (the longest run of unresolved epochs) and ``gap_oracle`` (the same where the
oracle measures: the generalisation summary's gap*, issue 11's "no run of more than 3
epochs without a measurement where the oracle measures"). Writes a CSV (one row per world,
noise and variant). Used by SPLIT2D (docs/RESULTS.md) to measure the deskewing passes
(``odometry.deskew_passes``, the motion between the neighbouring epochs' solved poses)
with and without the gated moments' solve on seen worlds:

    uv run python experiments/rig2d_variants.py --worlds 340,346 --noise 0.006 0.02 \\
        --epochs 150 --oracle INGREDIENTS.csv -o OUT.csv \\
        --variant default \\
        --variant passes odometry.deskew_passes=2 \\
        --variant passes+moments odometry.deskew_passes=2 odometry.refinement=moments \\
            odometry.moment_gate_chi2=20.5
"""

from __future__ import annotations

import argparse
import csv
import time
from collections.abc import Sequence

import numpy as np
import yaml

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, longest_run, world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.oracle import run_oracle
from planodom.results import write_rows
from planodom.simulation.random_world import simulate_world, world_fields


def metrics(poses: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    """Per-epoch rotation (deg) and xy (m) rms, ATE xy (m), as ``generalisation``."""
    err = per_epoch_errors(relative_motions(poses), relative_motions(gt))
    rot = np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))
    xy = np.hypot(err["x"], err["y"])
    return {
        "rot_rms_deg": float(np.sqrt(np.mean(rot**2))),
        "xy_rms_m": float(np.sqrt(np.mean(xy**2))),
        "ate_xy_m": float(ate(poses, gt, align="origin", xy_only=True)["rmse"]),
    }


def oracle_rows(path: str | None) -> dict[tuple[int, float], dict[str, float]]:
    """(world, noise) -> the oracle's figures from a ``rig2d_ingredients.py`` CSV."""
    if path is None:
        return {}
    with open(path, newline="") as f:
        return {
            (int(r["world"]), float(r["noise_m"])): {
                k: float(r[k]) for k in ("rot_rms_deg", "xy_rms_m", "ate_xy_m")
            }
            for r in csv.DictReader(f)
            if r["variant"] == "oracle"
        }


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worlds", default="340,346")
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--oracle", default=None, help="rig2d_ingredients.py CSV (oracle rows)")
    ap.add_argument("-o", "--out", default=None, help="CSV of the rows")
    ap.add_argument("--gaps", action="store_true", help="gap and gap* against the oracle")
    ap.add_argument(
        "--variant", nargs="+", action="append", required=True,
        help="NAME [KEY=VALUE ...] (repeat per variant)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    variants = []
    for name, *sets in args.variant:
        changes = {k: yaml.safe_load(v) for k, v in (kv.split("=", 1) for kv in sets)}
        cfg = PlanodomConfig().updated(changes, source=name) if changes else PlanodomConfig()
        variants.append((name, cfg))
    oracle = oracle_rows(args.oracle)
    rows: list[dict] = []
    for w in (int(x) for x in args.worlds.split(",")):
        world = world_for(w)
        for noise in args.noise:
            full = simulate_world(world, noise, n_epochs=args.epochs, all_fields=True)
            run = world_fields(world, full)
            gt = invert_transform(full.poses[0])[None] @ full.poses
            ref = oracle.get((w, noise))
            measures = None  # per epoch: whether the oracle measures it (--gaps)
            if args.gaps:
                orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
                measures = np.array(orc.statuses) != "unresolved"
            for name, cfg in variants:
                c0 = time.process_time()
                odo = run_odometry(run, declared_sweep(world, cfg))
                cpu = time.process_time() - c0
                m = metrics(odo.poses, gt)
                row: dict[str, object] = {"world": w, "noise_m": noise, "variant": name}
                row |= m
                if ref is not None:
                    row |= {f"{k}_x_oracle": m[k] / ref[k] for k in m}
                st = np.array(odo.statuses)
                row |= {"unresolved": int((st == "unresolved").sum()), "cpu_s": cpu}
                if measures is not None:
                    lost = st == "unresolved"
                    row |= {"gap": longest_run(lost), "gap_oracle": longest_run(lost & measures)}
                # extractor calls over all passes, and those given the streaming pass's
                # planes (odometry.deskew_pass_skip)
                row |= {"extractions": odo.extractions, "reused": odo.reused}
                rows.append(row)
                figures = {k: round(float(v), 5) for k, v in m.items()}
                print(w, noise, name, figures, row["unresolved"], row.get("gap_oracle", ""),
                      round(cpu, 1), odo.extractions, odo.reused, flush=True)  # fmt: skip
                if args.out:
                    write_rows(args.out, rows)


if __name__ == "__main__":
    main()
