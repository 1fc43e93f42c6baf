"""Where a built-in random scene's heading is lost, default against an option (issue 11).

The scene (``planodom run --scenario`` defaults, as ``builtin_scenes.py``, with noise seed
``--noise-seed``: the world stays seed 0's) is run with the default config and with the
``--set`` overrides; with ``--exact`` every extraction is made from the points deskewed
exactly (the oracle's :func:`planodom.oracle.deskewed_points`; the twist the odometry
asks for is ignored, but its step's rate still gets the deskewing's ``twist_offset``).
Per run: ATE xy (m, origin-aligned), unresolved epochs, and per segment of ``--cuts``
the summed yaw error of its steps (deg; a step's error is the rotation vector of
``inv(T_true) @ T_est``) and its ATE xy aligned at its first epoch. Then, per step of
``--steps``: the truth's yaw step (deg), and per run the status, the planes' true
surfaces with each wall's normal error in yaw (deg, against its true surface), the
step's yaw error (deg) and the yaw rate its epoch was extracted with (deg/s; the true
one last); and the oracle's status and planes there (:func:`planodom.oracle.run_oracle`).
With ``--bridge-median N`` both runs bridge an unresolved epoch with the median angular
rate of the last N measured steps instead of the last one's (``odometry.bridge_rate:
median``, ``bridge_median_steps: N``, added to both runs' overrides).

    uv run python experiments/builtin_stretch.py --scene random-outdoor --noise 0.02 \\
        --set extraction.noise_estimate=range --cuts 549 600 --steps 558 578
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from builtin_scenes import config_with, simulated, true_twist
from scipy.spatial.transform import Rotation

from planodom.extraction import extract_planes
from planodom.geometry import invert_transform
from planodom.metrics import ate
from planodom.odometry import run_odometry
from planodom.oracle import deskewed_points, run_oracle
from planodom.simulation.named import RANDOM_SCENES
from planodom.simulation.random_world import random_world, simulate_world
from planodom.simulation.rigs import rig_from_name


def simulated_seed(scene: str, noise: float, seed: int):  # noqa: ANN201
    """The random ``scene`` as ``simulated`` gives it (world of seed 0, isoclinal rig) with
    noise seed ``seed``, and its true poses (E, 4, 4) in the first pose's frame."""
    if seed == 0:
        return simulated(scene, str(noise))
    world = random_world(0, RANDOM_SCENES[scene], None, "vehicle")
    world = dataclasses.replace(world, sensor_rig=rig_from_name("isoclinal"), epoch_rate=10.0,
                                ring_field=True, time_field=True)  # fmt: skip
    sim = simulate_world(world, noise, seed=seed)
    return sim, invert_transform(sim.poses[0])[None] @ sim.poses


def exact_extractor(sim):  # noqa: ANN001, ANN201
    """An extractor that ignores the twist and extracts the exactly deskewed points."""
    index = {s.points[:3].tobytes(): k for k, s in enumerate(sim.scans)}
    cache: dict = {}

    def extractor(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN003, ANN202
        k = index[scan.points[:3].tobytes()]
        if k not in cache:
            points = deskewed_points(sim.scans[k], sim.trajectory, float(sim.times[k]))
            cache[k] = dataclasses.replace(sim.scans[k], points=points)
        return extract_planes(cache[k], config, np.zeros(6), **kwargs)

    return extractor


def yaw_errors(poses: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """(E,) each step's yaw error (deg), 0 for the first epoch."""
    out = np.zeros(len(gt))
    for k in range(1, len(gt)):
        T_true = invert_transform(gt[k - 1]) @ gt[k]
        E = invert_transform(T_true) @ invert_transform(poses[k - 1]) @ poses[k]
        out[k] = np.degrees(Rotation.from_matrix(E[:3, :3]).as_rotvec()[2])
    return out


def wall_cells(sim, planes, k: int) -> str:  # noqa: ANN001
    """The planes' true surfaces, each wall's (|n_z| < 0.5) yaw error (deg)."""
    ids = {int(i): j for j, i in enumerate(sim.scene.ids)}
    R = invert_transform(sim.poses[k])[:3, :3]
    cells = []
    for p in planes:
        j = ids.get(int(p.truth_id))
        if j is None or abs(p.normal[2]) >= 0.5:
            cells.append(str(p.truth_id))
            continue
        n = R @ sim.scene.normals[j]
        d = np.degrees(np.arctan2(p.normal[1], p.normal[0]) - np.arctan2(n[1], n[0]))
        d = (d + 90.0) % 180.0 - 90.0  # a normal's sign does not matter here
        cells.append(f"{p.truth_id}({d:+.2f})")
    return " ".join(cells)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="random-outdoor", choices=list(RANDOM_SCENES))
    parser.add_argument("--noise", type=float, default=0.02, help="range noise, m")
    parser.add_argument("--noise-seed", type=int, default=0)
    parser.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    parser.add_argument("--exact", action="store_true", help="extract exactly deskewed points")
    parser.add_argument("--cuts", type=int, nargs="*", default=[], help="segment bounds")
    parser.add_argument("--steps", type=int, nargs=2, default=None, help="first last")
    parser.add_argument("--bridge-median", type=int, default=None, help="what-if: N rates")
    args = parser.parse_args()
    sim, gt = simulated_seed(args.scene, args.noise, args.noise_seed)
    extractor = exact_extractor(sim) if args.exact else None
    median = (
        []
        if args.bridge_median is None
        else ["odometry.bridge_rate=median", f"odometry.bridge_median_steps={args.bridge_median}"]
    )
    runs = {name: run_odometry(sim, config_with(median + sets), sim.rig, extractor=extractor)
            for name, sets in (("default", []), ("option", args.set))}  # fmt: skip
    bounds = [0, *args.cuts, len(gt) - 1]
    errors = {}
    for name, run in runs.items():
        e = errors[name] = yaw_errors(run.poses, gt)
        cells = [f"[{a},{b}] yaw {e[a + 1 : b + 1].sum():+.2f} ATE "
                 f"{ate(run.poses[a : b + 1], gt[a : b + 1], 'origin', xy_only=True)['rmse']:.3f}"
                 for a, b in zip(bounds[:-1], bounds[1:], strict=True)]  # fmt: skip
        a = ate(run.poses, gt, align="origin", xy_only=True)["rmse"]
        print(f"{name}: ATE xy {a:.3f} m, unresolved {run.n_unresolved}; " + "; ".join(cells))
    if args.steps is None:
        return
    oracle = run_oracle(sim.scans, sim.times, sim.trajectory, sim.scene)
    for k in range(args.steps[0], args.steps[1] + 1):
        T_true = invert_transform(gt[k - 1]) @ gt[k]
        true_yaw = np.degrees(Rotation.from_matrix(T_true[:3, :3]).as_rotvec()[2])
        cells = []
        for name, run in runs.items():
            r = run.results[k]
            rate = "none" if r is None or r.deskew_twist is None else (
                f"{np.degrees(r.deskew_twist[2]):+.1f}")  # fmt: skip
            cells.append(f"{name} {run.statuses[k][:5]} [{wall_cells(sim, run.planes[k], k)}] "
                         f"{errors[name][k]:+.2f} {rate}")  # fmt: skip
        print(f"{k} true {true_yaw:+.2f} | " + " | ".join(cells)
              + f" | true rate {np.degrees(true_twist(sim, k)[2]):+.1f} | oracle "
              f"{oracle.statuses[k]} {oracle.n_planes[k]}")  # fmt: skip


if __name__ == "__main__":
    main()
