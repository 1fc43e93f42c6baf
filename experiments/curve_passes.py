"""The deskewing passes along the curve through the neighbouring poses, on lidar worlds,
against the oracle and the true-motion deskewing floor (issue 11, LIDARCURVE).

``uv run python experiments/curve_passes.py --worlds 181 183 ... --noise 0.006 0.02
[--epochs 150] [--variants epoch1,mid1,mid2] [--no-floor] [--out FILE.jsonl]``: for each
world (odd: a lidar, as the generalisation experiment draws it) and noise, one simulated
run; the oracle; planodom's default (the streaming pass, ``run``); then, from that same
streaming pass, the passes deskewed along the curve through its poses:

- ``epochN``: ``odometry.deskew_passes: N`` as it is (passes to the epoch middles, the
  last registered at the epoch times: :func:`planodom.odometry.run.redeskewed_run`);
- ``midN``: the same with ``planemap.pass_reference_time: middle`` (every pass at the
  sweeps' middles, the nodes the streaming pass's own middle poses:
  :func:`planodom.odometry.middle_passes.middle_redeskewed_run`);

and ``floor``: the scans deskewed along the true motion to the epoch times, the default
otherwise (:func:`lidar_floor.truly_deskewed`, its ``true`` variant). One line per run:
rotation rms per step (deg), xy rms per step (cm), ATE (xy, aligned at the origin, mm),
each with its ratio to the oracle, unresolved epochs and the variant's own CPU seconds
(the passes: their own, the streaming pass not counted again). The metrics are the
generalisation experiment's (:func:`planodom.experiments.generalisation._metrics`), and
``run`` is what ``run_odometry`` returns with the default configuration (the passes
reuse its streaming pass rather than running it again). ``--out``: one JSON line per run.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

# the floor's true-motion deskewing (this script runs beside it in experiments/)
from handheld_walks import _Scans
from lidar_floor import truly_deskewed

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import MethodRun, _metrics, declared_sweep
from planodom.extraction.lidar.sweep import sweep_timed
from planodom.odometry import run_odometry
from planodom.odometry.middle_passes import middle_redeskewed_run
from planodom.odometry.run import (
    _middle_timed_pass,
    _streaming_pass,
    redeskewed_run,
    with_motion_bounds,
)
from planodom.oracle import run_oracle
from planodom.rig import Rig


def _line(world: int, noise: float, name: str, m: dict, o: dict, cpu: float) -> dict:
    row = {"world": world, "noise": noise, "variant": name, "cpu_s": cpu} | m
    for key in ("rot_rms_deg", "xy_rms_m", "ate_xy_m"):
        row[f"x_{key}"] = m[key] / o[key] if o[key] > 0 else float("nan")
    print(f"world {world} {noise * 1000:g} mm {name:>7}: rot {m['rot_rms_deg']:.5f} "
          f"({row['x_rot_rms_deg']:.1f}x) xy {100 * m['xy_rms_m']:.4f} cm "
          f"({row['x_xy_rms_m']:.2f}x) ATE {1000 * m['ate_xy_m']:.2f} mm "
          f"({row['x_ate_xy_m']:.1f}x) unresolved {m['unresolved']:.0f} CPU {cpu:.1f} s",
          flush=True)  # fmt: skip
    return row


def one_world(index: int, noise: float, epochs: int, variants: list[str], floor: bool) -> list:
    """The rows of world ``index`` at ``noise`` (m) (module docstring)."""
    world, full, data, gt, scans, _ = truly_deskewed(index, noise, epochs)
    fam = world.description["family"]

    def metrics(name, poses, statuses, oracle_statuses):  # noqa: ANN001, ANN202
        mr = MethodRun(index, world.kind, fam, noise, name, poses, statuses, 1.0, gt, None)
        return _metrics(mr, oracle_statuses)

    c0 = time.process_time()
    orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
    om = metrics("oracle", orc.poses, orc.statuses, None)
    rows = [_line(index, noise, "oracle", om, om, time.process_time() - c0)]
    cfg = declared_sweep(world, PlanodomConfig())
    rig = getattr(data, "rig", None) or Rig()
    cfg = with_motion_bounds(cfg, rig.motion_bounds)
    source = sweep_timed(data, cfg.extraction.sweep, rig)
    times = np.asarray(data.times, dtype=np.float64)
    c0 = time.process_time()
    pair = _middle_timed_pass(source, cfg, rig, times, None, None)
    streaming = pair[0] if pair else _streaming_pass(source, cfg, rig, times, None, None)
    cpu = time.process_time() - c0
    rows.append(_line(index, noise, "run", metrics("run", streaming.poses, streaming.statuses,
                                                   orc.statuses), om, cpu))  # fmt: skip
    for name in variants:
        mode, passes = name[:-1], int(name[-1])
        c = cfg.updated({"odometry.deskew_passes": passes}, source="curve_passes")
        c0 = time.process_time()
        if mode == "mid" and pair is not None:
            run = middle_redeskewed_run(source, pair[1], streaming, c, rig)
        else:
            run = redeskewed_run(source, times, streaming.poses, c, rig, previous=streaming)
        cpu = time.process_time() - c0
        m = metrics(name, run.poses, run.statuses, orc.statuses)
        rows.append(_line(index, noise, name, m, om, cpu))
    if floor:
        c = declared_sweep(world, PlanodomConfig()).updated(
            {"odometry.deskew": False, "planemap.reference_time": "epoch"}, source="floor"
        )
        c0 = time.process_time()
        run = run_odometry(_Scans(scans, data.times), c)
        cpu = time.process_time() - c0
        m = metrics("floor", run.poses, run.statuses, orc.statuses)
        rows.append(_line(index, noise, "floor", m, om, cpu))
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--worlds", type=int, nargs="+", required=True)
    p.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    p.add_argument("--epochs", type=int, default=150)
    p.add_argument("--variants", default="epoch1,mid1,mid2")
    p.add_argument("--no-floor", action="store_true")
    p.add_argument("--out")
    args = p.parse_args()
    variants = [v for v in args.variants.split(",") if v]
    for noise in args.noise:
        for w in args.worlds:
            rows = one_world(w, noise, args.epochs, variants, not args.no_floor)
            if args.out:
                with open(args.out, "a") as f:
                    for row in rows:
                        f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
