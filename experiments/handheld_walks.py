"""Hand-held lidar walks (issue 11): where planodom goes wrong, against the truth.

``uv run python experiments/handheld_walks.py run W NOISE [--set KEY=VALUE ...]
[--oracle] [--true-deskew] [--vehicle] [--epochs N] [--out FILE.npz]``: planodom on the
hand-held world ``W`` (``world_for(W, "handheld")``; ``--vehicle``: the generalisation
experiment's world ``W``) at range noise NOISE (m), with the experiment's declared sweep
and the configuration overrides given; one line with the rotation and xy rms per epoch
(the steps after the first, deg / cm), ATE (xy, origin-aligned, m), unresolved and
degenerate epochs and the process's CPU seconds (as in ``planodom experiment
generalisation``); ``--out`` keeps per epoch the errors, statuses, hypotheses and poses
(and the oracle's with ``--oracle``). ``--true-deskew``: the scans deskewed to the epoch
times by the true motion, planodom's own deskewing off (``odometry.deskew: false``,
``planemap.reference_time: epoch``): what is left when the deskewing is right.

``... deskew W``: per sweep of the true trajectory, the rms rotation error (deg) over the
sweep of the motion models a streaming odometry could deskew with, from the true middle
poses: none, the previous step's constant twist, the step's own (what the refinement
converges to), the true rate at the sweep's middle, the polynomials through the last
two / three middles and the sweep's own (branch ``handheld``'s
``planemap.deskew_curve`` 2 / 3).

``... first-pose W``: the error (deg) of the first epoch's pose at its epoch time from
the true middle poses of the first epochs (:func:`planodom.odometry.planemap.midtime.
_pose_at`, the least-squares quadratic over five, against the interpolating quadratic
through three, the cubic through four and the geodesic through two).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.odometry.interpolate import curve_poses
from planodom.odometry.planemap.midtime import _pose_at
from planodom.oracle import run_oracle
from planodom.simulation.random_world import World, simulate_world, world_fields


def _angle_deg(A: np.ndarray, B: np.ndarray) -> float:
    """Angle (deg) of the rotation between the (4, 4) or (3, 3) poses ``A`` and ``B``."""
    return float(
        np.degrees(np.linalg.norm(Rotation.from_matrix(A[:3, :3].T @ B[:3, :3]).as_rotvec()))
    )


def _errors(poses: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step (E - 1,) rotation error (deg) and xy error (m)."""
    e = per_epoch_errors(relative_motions(poses), relative_motions(gt))
    rot = np.degrees(np.sqrt(e["roll"] ** 2 + e["pitch"] ** 2 + e["yaw"] ** 2))
    return rot, np.hypot(e["x"], e["y"])


class _Scans:
    """The scans of a run as the odometry's epoch sequence (``len``, indexing, ``times``)."""

    def __init__(self, scans: list, times: np.ndarray) -> None:
        self.scans, self.times = scans, times

    def __len__(self) -> int:
        return len(self.scans)

    def __getitem__(self, k: int):  # noqa: ANN204
        return self.scans[k]


def _true_deskewed(world: World, full, data) -> _Scans:  # noqa: ANN001
    """The scans of ``data`` (the world's fields) with their points brought to the epoch
    times by the true motion at the times of ``full`` (all fields: the simulator's)."""
    out = []
    for k, (scan, timed) in enumerate(zip(data.scans, full.scans, strict=True)):
        t_k = full.times[k]
        M = invert_transform(world.trajectory.pose(t_k))[None] @ world.trajectory.poses(
            t_k + timed.t
        )
        points = np.einsum("nij,nj->ni", M[:, :3, :3], timed.points) + M[:, :3, 3]
        out.append(replace(scan, points=points))
    return _Scans(out, data.times)


def run(args: argparse.Namespace) -> None:
    """The ``run`` command (module docstring)."""
    world = world_for(args.world, "vehicle" if args.vehicle else "handheld")
    full = simulate_world(world, args.noise, n_epochs=args.epochs, all_fields=True)
    data = world_fields(world, full)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    cfg = declared_sweep(world, PlanodomConfig())
    overrides: dict[str, object] = {}
    for item in args.set:
        key, value = item.split("=", 1)
        overrides[key] = yaml.safe_load(value)  # numbers as numbers
    if args.true_deskew:
        overrides |= {"odometry.deskew": False, "planemap.reference_time": "epoch"}
    if overrides:
        cfg = cfg.updated(overrides, source="handheld_walks")
    source = _true_deskewed(world, full, data) if args.true_deskew else data
    c0 = time.process_time()
    odo = run_odometry(source, cfg)
    cpu = time.process_time() - c0
    rot, xy = _errors(odo.poses, gt)
    statuses = np.array(odo.statuses)
    a = ate(odo.poses, gt, align="origin", xy_only=True)["rmse"]
    print(
        f"world {args.world} {world.description['family']} {world.epoch_rate:g} Hz, "
        f"{args.noise * 1000:g} mm: rotation {np.sqrt(np.mean(rot**2)):.4f} deg, xy "
        f"{100 * np.sqrt(np.mean(xy**2)):.3f} cm, ATE {a:.4f} m, unresolved "
        f"{(statuses == 'unresolved').sum()}, degenerate {(statuses == 'degenerate').sum()}, "
        f"CPU {cpu:.1f} s"
    )
    if args.out:
        stages = ["" if r is None or r.diagnostics is None else r.diagnostics.pipeline
                  for r in odo.results]  # fmt: skip
        out: dict[str, np.ndarray] = {"rot": rot, "xy": xy, "poses": odo.poses, "gt": gt,
                                      "n_planes": odo.n_planes, "status": statuses,
                                      "stage": np.array(stages)}  # fmt: skip
        if args.oracle:
            orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
            out["orot"], out["oxy"] = _errors(orc.poses, gt)
        np.savez(args.out, **out)  # type: ignore[arg-type]


Model = Callable[[int, np.ndarray], np.ndarray]


def deskew(args: argparse.Namespace) -> None:
    """The ``deskew`` command (module docstring)."""
    world = world_for(args.world, "handheld")
    period = 1.0 / world.epoch_rate
    mids = (np.arange(args.epochs) + 0.5) * period
    M = world.trajectory.poses(mids)

    def constant(twist: Callable[[int], np.ndarray]) -> Model:
        return lambda k, ts: se3_exp(np.outer(ts - mids[k], twist(k)))

    def curve(order: int) -> Model:
        def model(k: int, ts: np.ndarray) -> np.ndarray:
            idx = np.arange(k - order, k + 1)
            P = curve_poses(mids[idx], M[idx], mids[k], np.r_[mids[k], ts], order)
            return invert_transform(P[0])[None] @ P[1:]

        return model

    def rate(k: int) -> np.ndarray:
        h = 1e-3
        pair = world.trajectory.poses(np.array([mids[k] - h, mids[k] + h]))
        return se3_log(invert_transform(pair[0]) @ pair[1]) / (2 * h)

    models: dict[str, Model] = {
        "none": constant(lambda k: np.zeros(6)),
        "previous step": constant(
            lambda k: se3_log(invert_transform(M[k - 2]) @ M[k - 1]) / period
        ),
        "own step": constant(lambda k: se3_log(invert_transform(M[k - 1]) @ M[k]) / period),
        "true middle rate": constant(rate),
        "quadratic": curve(2),
        "cubic": curve(3),
    }
    print(
        f"world {args.world}: {world.epoch_rate:g} Hz, swing {world.description['swing_hz']:.2f} Hz"
    )
    for name, model in models.items():
        per_sweep = []
        for k in range(4, args.epochs):
            ts = mids[k] + np.linspace(-period / 2, period / 2, 11)
            true = invert_transform(M[k])[None] @ world.trajectory.poses(ts)
            est = model(k, ts)
            angles = [_angle_deg(a, b) for a, b in zip(true, est, strict=True)]
            per_sweep.append(np.sqrt(np.mean(np.square(angles))))
        print(f"  {name:17s} median {np.median(per_sweep):.3f}, worst {np.max(per_sweep):.3f} deg")


def first_pose(args: argparse.Namespace) -> None:
    """The ``first-pose`` command (module docstring)."""
    world = world_for(args.world, "vehicle" if args.vehicle else "handheld")
    period = 1.0 / world.epoch_rate
    mids = (np.arange(8) + 0.5) * period
    M = world.trajectory.poses(mids)
    truth = world.trajectory.pose(0.0)
    at0 = np.array([0.0])
    fits = {
        "least-squares quadratic (5)": _pose_at(mids, M, 0.0, 3),
        "quadratic (3)": curve_poses(mids[:3], M[:3], 0.0, at0, 2)[0],
        "cubic (4)": curve_poses(mids[:4], M[:4], 0.0, at0, 3)[0],
        "geodesic (2)": curve_poses(mids[:2], M[:2], 0.0, at0, 1)[0],
    }
    print(
        f"world {args.world}: "
        + ", ".join(f"{k} {_angle_deg(truth, v):.3f}" for k, v in fits.items())
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run")
    p.add_argument("world", type=int)
    p.add_argument("noise", type=float)
    p.add_argument("--epochs", type=int, default=150)
    p.add_argument("--set", action="append", default=[], help="KEY=VALUE config override")
    p.add_argument("--oracle", action="store_true")
    p.add_argument("--true-deskew", action="store_true")
    p.add_argument("--vehicle", action="store_true")
    p.add_argument("--out")
    p.set_defaults(func=run)
    p = sub.add_parser("deskew")
    p.add_argument("world", type=int)
    p.add_argument("--epochs", type=int, default=150)
    p.set_defaults(func=deskew)
    p = sub.add_parser("first-pose")
    p.add_argument("world", type=int)
    p.add_argument("--vehicle", action="store_true")
    p.set_defaults(func=first_pose)
    args = parser.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
