"""Which part of a lidar run's deskewing twist holds its rotation error (issue 11, LIDAR15).

``uv run python experiments/lidar_twist_parts.py W NOISE [--epochs N] [--cache DIR]
--variants V[,V...]``: the generalisation experiment's world ``W`` (odd: a lidar) at range
noise NOISE (m), simulated once (kept with ``--cache`` as :mod:`lidar_epoch_trace` keeps
it), then planodom's odometry once per variant on the same scans, one line each: the
rotation rms per step over all steps and over steps 3 on (0.001 deg), per axis (roll,
pitch, yaw) over steps 3 on, the ATE (xy, aligned at the origin, mm), the first three
steps' signed errors (roll, pitch, yaw, 0.001 deg), the CPU and the extractions made,
and the rms error of the twist each epoch was last extracted with against its sweep's
true constant twist (``log(T(t0)^-1 T(t1)) / (t1 - t0)`` over the sweep's first and last
point times; epochs 3 on; rates deg/s, velocity cm/s). A variant's parts, joined by ``+``:

- ``run``: planodom as the experiment runs it (the world's sweep declared);
- ``skipN``: the first N epochs dropped (the run starts at epoch N): whether the start's
  error belongs to the first scan or to any start;
- ``ttwist`` / ``tdesk``: :mod:`lidar_split`'s, every extraction given its sweep's true
  constant twist / the points moved along the true motion;
- ``subIJ..``: the twist every extraction is given with its components I, J, ... (0-2 the
  rates roll, pitch, yaw; 3-5 the velocity x, y, z) replaced by the sweep's true constant
  twist's (the rest as the odometry gives it): which part of the twist's error matters;
- ``KEY=VALUE``: a configuration override (``odometry.map_lead_rate_tolerance_deg_s=0.05``).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
import yaml

# the world simulated and cached, the signed per-step errors; the scans' identity
from lidar_epoch_trace import signed, simulated
from lidar_floor import _key
from lidar_split import _true_deskew_extractor

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep
from planodom.extraction import extract_planes
from planodom.geometry import invert_transform, se3_log
from planodom.metrics import ate
from planodom.odometry import run_odometry


def true_twists(full, world) -> np.ndarray:  # noqa: ANN001
    """(E, 6) each sweep's true constant body twist (rad/s, m/s) over its point times."""
    out = []
    for k, scan in enumerate(full.scans):
        span = np.array([scan.t.min(), scan.t.max()]) + float(full.times[k])
        T = world.trajectory.poses(span)
        out.append(se3_log(invert_transform(T[0]) @ T[1]) / (span[1] - span[0]))
    return np.array(out)


def recording_extractor(scans, truth: np.ndarray, parts: list[int], inner=None):  # noqa: ANN001, ANN201
    """An extractor that records the twist (6,) each epoch of ``scans`` was last given
    (``extract.last``: epoch -> twist) and gives it with the ``parts`` of the sweep's
    ``truth`` (E, 6) in place (``parts`` empty: as the odometry gives it, ``parts`` all:
    :mod:`lidar_split`'s ``ttwist``); ``inner`` (an extractor) in place of the library's."""
    index = {_key(s): k for k, s in enumerate(scans)}
    last: dict[int, np.ndarray] = {}

    def extract(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN202
        k = index.get(_key(scan))
        extract.calls += 1  # type: ignore[attr-defined]
        if k is not None:
            last[k] = np.zeros(6) if twist is None else np.array(twist, dtype=np.float64)
            if parts:
                twist = last[k].copy()
                twist[parts] = truth[k][parts]
        return (inner or extract_planes)(scan, config, twist=twist, **kwargs)

    extract.last, extract.calls = last, 0  # type: ignore[attr-defined]
    return extract


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("world", type=int)
    p.add_argument("noise", type=float)
    p.add_argument("--epochs", type=int, default=150)
    p.add_argument("--cache")
    p.add_argument("--variants", default="run")
    args = p.parse_args()
    world, full, data, gt = simulated(args.world, args.noise, args.epochs, args.cache)
    truth = true_twists(full, world)
    base = declared_sweep(world, PlanodomConfig())
    for variant in args.variants.split(","):
        source, g, cfg, skip, parts, inner = data, gt, base, 0, [], None
        for part in variant.split("+"):
            if part.startswith("skip"):
                skip = int(part[4:])
            elif part.startswith("sub"):
                parts = [int(c) for c in part[3:]]
            elif part == "ttwist":
                parts = list(range(6))
            elif part == "tdesk":
                inner = _true_deskew_extractor(data.scans, full, world)
            elif "=" in part:
                key, value = part.split("=", 1)  # "off" / "on" stay words
                value = value if value in ("off", "on") else yaml.safe_load(value)
                cfg = cfg.updated({key: value}, source="lidar_twist_parts")
        if skip:
            n = len(data.scans)
            fields = ("scans", "times", "poses", "sweep_starts", "ranges")
            per_epoch = [f for f in fields if hasattr(getattr(data, f, None), "__len__")]
            cut = {f: getattr(data, f)[skip:] for f in per_epoch if len(getattr(data, f)) == n}
            source = replace(data, **cut)
            g = invert_transform(gt[skip])[None] @ gt[skip:]
        extract = recording_extractor(source.scans, truth[skip:], parts, inner)
        c0 = time.process_time()
        odo = run_odometry(source, cfg, extractor=extract)
        cpu = time.process_time() - c0
        e = signed(odo.poses, g)
        rot = np.linalg.norm(e[:, :3], axis=1)
        a = ate(odo.poses, g, align="origin", xy_only=True)["rmse"]
        used = extract.last
        ks = [k for k in sorted(used) if k >= 3]
        err = np.array([used[k] - truth[skip + k] for k in ks])
        terr = np.sqrt(np.mean(err**2, axis=0)) if len(err) else np.full(6, np.nan)
        head = [np.round(1000 * e[k, :3], 1).tolist() for k in range(min(3, len(e)))]
        rms, tail = np.sqrt(np.mean(rot**2)), np.sqrt(np.mean(rot[2:] ** 2))
        print(f"{args.world} {args.noise * 1000:g} mm {variant}: rot {1000 * rms:.3f}"
              f" / 3+ {1000 * tail:.3f} axes 3+ "
              f"{np.round(1000 * np.sqrt(np.mean(e[2:, :3] ** 2, 0)), 3).tolist()} ATE "
              f"{1000 * a:.2f} mm steps 1-3 {head} CPU {cpu:.0f} s, {extract.calls} extractions; "
              f"twist error rate "
              f"{np.round(np.degrees(terr[:3]), 3).tolist()} deg/s velocity "
              f"{np.round(100 * terr[3:], 2).tolist()} cm/s", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
