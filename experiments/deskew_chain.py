"""Why a 2D-rig world's OK steps are biased, against the truth (issue 11, RANGE166).

One generalisation world (``world_for``, as ``planodom experiment generalisation`` runs
it) is run with the default config and with the ``--set`` overrides (the option), and
each run again with every extraction made from the points deskewed exactly (the oracle's
:func:`planodom.oracle.deskewed_points`, the twist the odometry asks for ignored). Per
run: unresolved epochs, heading error at ``--at`` epochs (deg, rotation vector's z), ATE xy
(m, origin-aligned, as the generalisation experiment). Then, per step of ``--steps`` of the
option's run: status, the winning pairs' true surfaces, the roll / pitch / yaw error of the
step and its stated sigma (deg), the roll / pitch / yaw rate the epoch was deskewed with
against the true rate (deg/s), and the same step solved again from both epochs extracted
from exactly deskewed points (true motion as the prior). Last, per epoch of the steps,
the planes of the exactly deskewed points under the default config and under the option:
true surface, normal error (deg), inliers, the share of inliers labelled with it; and
the option's run's own planes (true surface, normal error).

    uv run python experiments/deskew_chain.py --world 166 --noise 0.02 --steps 52 60 \
        --set extraction.noise_estimate=range
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from builtin_scenes import config_with
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.extraction import extract_planes
from planodom.extraction.pipeline import extract
from planodom.geometry import invert_transform
from planodom.metrics import ate
from planodom.odometry import run_odometry
from planodom.odometry.solver import estimate_relative_pose
from planodom.oracle import deskewed_points
from planodom.simulation.random_world import simulate_world, world_fields


def rotation_error_deg(T_est: np.ndarray, T_true: np.ndarray) -> np.ndarray:
    """(3,) rotation vector (deg) of ``inv(T_true) @ T_est``, both (4, 4)."""
    E = invert_transform(T_true) @ T_est
    return np.degrees(Rotation.from_matrix(E[:3, :3]).as_rotvec())


def exact_scan(sim, run, k: int):  # noqa: ANN001, ANN201
    """Epoch ``k`` of ``run`` with its points deskewed exactly."""
    points = deskewed_points(sim.scans[k], sim.trajectory, float(sim.times[k]))
    return dataclasses.replace(run.scans[k], points=points)


def exact_extractor(sim, run):  # noqa: ANN001, ANN201
    """An extractor that ignores the twist and extracts the exactly deskewed points."""
    index = {s.points[:3].tobytes(): k for k, s in enumerate(run.scans)}
    cache: dict = {}

    def extractor(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        k = index[scan.points[:3].tobytes()]
        if k not in cache:
            cache[k] = exact_scan(sim, run, k)
        return extract_planes(cache[k], config, np.zeros(6), **kwargs)

    return extractor


def true_rate(sim, k: int) -> np.ndarray:  # noqa: ANN001
    """(3,) the true body angular rate at epoch ``k`` (rad/s, central difference)."""
    a, b = max(k - 1, 0), min(k + 1, len(sim.poses) - 1)
    dt = float(sim.times[b] - sim.times[a])
    rel = invert_transform(sim.poses[a]) @ sim.poses[b]
    return Rotation.from_matrix(rel[:3, :3]).as_rotvec() / dt


def summary(name: str, odo, gt: np.ndarray, at: list[int]) -> None:  # noqa: ANN001
    """One line: unresolved, heading errors at ``at``, ATE xy."""
    heading = " ".join(
        f"{k}:{rotation_error_deg(odo.poses[k], gt[k])[2]:+.2f}" for k in at if k < len(gt)
    )
    a = ate(odo.poses, gt, align="origin", xy_only=True)["rmse"]
    print(f"{name:16s} unresolved {odo.n_unresolved:3d}  heading error (deg) {heading}  "
          f"ATE xy {a:.3f} m")  # fmt: skip


def fmt3(v: np.ndarray) -> str:
    return "(" + ",".join(f"{x:+.2f}" for x in v) + ")"


def step_rows(sim, run, odo, config: PlanodomConfig, steps: range) -> None:  # noqa: ANN001
    """The option's steps (module docstring)."""
    for k in steps:
        r = odo.results[k]
        T_true = invert_transform(sim.poses[r.prev]) @ sim.poses[k]
        P, C = odo.planes[r.prev], odo.planes[k]
        src = None if r.sources is None else [
            (P[i].truth_id if i < len(P) else "?", C[j].truth_id if j < len(C) else "?")
            for i, j in r.sources
        ]  # fmt: skip
        sig = np.degrees(np.sqrt(np.diag(r.covariance)[:3])) if r.covariance is not None else None
        tw = "none" if r.deskew_twist is None else fmt3(np.degrees(r.deskew_twist[:3]))
        a, b = (
            extract(exact_scan(sim, run, j), config.extraction, np.zeros(6),
                    sim.rig.sensor_origins).planes
            for j in (r.prev, k)
        )  # fmt: skip
        ex = estimate_relative_pose(a, b, config, T_true)
        print(f"step {k} (from {r.prev}) {r.status}: pairs {src}  error r/p/y "
              f"{fmt3(rotation_error_deg(r.T_prev_curr, T_true))} sigma "
              f"{'none' if sig is None else fmt3(sig)}  deskewed with {tw} true "
              f"{fmt3(np.degrees(true_rate(sim, k)))}  exact deskew: {ex.status} "
              f"{fmt3(rotation_error_deg(ex.T_prev_curr, T_true))}  the same pairs "
              f"covariance-weighted: {weighted_pairs(P, C, r.sources, T_true)}")  # fmt: skip


def weighted_pairs(P, C, sources, T_true: np.ndarray) -> str:  # noqa: ANN001
    """The rotation error (deg) of the step's winning pairs ``sources`` (S, 2) fitted by
    Procrustes weighted by the inverse normal variance (trace, both planes) instead of
    the consensus's frame, which fits its first normal exactly; "-" without two pairs."""
    if sources is None or len(sources) < 2 or max(i for i, _ in sources) >= len(P):
        return "-"
    if max(j for _, j in sources) >= len(C):
        return "-"
    pairs = [(P[i], C[j]) for i, j in sources]
    if any(p.covariance is None or c.covariance is None for p, c in pairs):
        return "-"
    var = [np.trace(p.covariance[:3, :3]) + np.trace(c.covariance[:3, :3]) for p, c in pairs]
    n_p = np.array([p.normal for p, _ in pairs])
    n_c = np.array([c.normal for _, c in pairs])
    rot, _ = Rotation.align_vectors(n_p, n_c, weights=1.0 / (np.array(var) + 1e-12))
    T = np.eye(4)
    T[:3, :3] = rot.as_matrix()
    return fmt3(rotation_error_deg(T, T_true))


def census(sim, odo, name: str) -> None:  # noqa: ANN001
    """Measured steps (OK or degenerate, not gated) whose winning pairs hold no
    near-horizontal plane (|n_z| > 0.5: walls only) or one: count, roll/pitch error rms."""
    groups: dict[str, list[float]] = {"walls only": [], "with the ground": []}
    for k, r in enumerate(odo.results):
        if r is None or r.sources is None or r.inconsistent or str(r.status) == "unresolved":
            continue
        P = odo.planes[r.prev]
        ground = any(abs(P[i].normal[2]) > 0.5 for i, _ in r.sources if i < len(P))
        T_true = invert_transform(sim.poses[r.prev]) @ sim.poses[k]
        e = rotation_error_deg(r.T_prev_curr, T_true)
        groups["with the ground" if ground else "walls only"].append(float(np.hypot(*e[:2])))
    cells = [f"{key} {len(v)} steps, roll/pitch rms {np.sqrt(np.mean(np.square(v))):.2f} deg"
             for key, v in groups.items() if v]  # fmt: skip
    print(f"{name}: " + "; ".join(cells))


def plane_rows(sim, run, configs: dict[str, PlanodomConfig], epochs: range, odo) -> None:  # noqa: ANN001
    """Planes of the exactly deskewed epochs under each config (module docstring), and
    the option's run's own planes (``odo``): true surface and normal error (deg)."""
    scene = sim.scene
    ids = {int(i): j for j, i in enumerate(scene.ids)}
    for k in epochs:
        R_base_world = invert_transform(sim.poses[k])[:3, :3]
        labels = run.scans[k].label
        for name, config in configs.items():
            found = extract(exact_scan(sim, run, k), config.extraction, np.zeros(6),
                            sim.rig.sensor_origins)  # fmt: skip
            cells = []
            for p, inl in zip(found.planes, found.inliers, strict=True):
                j = ids.get(int(p.truth_id))
                if j is None:
                    cells.append(f"{p.truth_id}:?")
                    continue
                n = R_base_world @ scene.normals[j]
                err = np.degrees(np.arccos(min(1.0, abs(float(p.normal @ n)))))
                pure = float(np.mean(labels[inl] == p.truth_id))
                cells.append(f"{p.truth_id}:{err:.2f}deg/{len(inl)}/{pure:.2f}")
            print(f"epoch {k} {name} sigma {found.sigma_m * 100:.2f} cm: {' '.join(cells)}")
        own = []
        for p in odo.planes[k]:
            j = ids.get(int(p.truth_id))
            n = R_base_world @ scene.normals[j] if j is not None else p.normal
            err = np.degrees(np.arccos(min(1.0, abs(float(p.normal @ n)))))
            own.append(f"{p.truth_id}:{err:.2f}deg" if j is not None else f"{p.truth_id}:?")
        print(f"epoch {k} option's run: {' '.join(own)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", type=int, default=166)
    parser.add_argument("--noise", type=float, default=0.02, help="range noise, m")
    parser.add_argument("--epochs", type=int, default=150)
    parser.add_argument("--steps", type=int, nargs=2, default=[52, 60], help="first last")
    parser.add_argument("--at", type=int, nargs="*", default=[56, 59, 75, 149])
    parser.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    args = parser.parse_args()
    world = world_for(args.world)
    sim = simulate_world(world, args.noise, n_epochs=args.epochs, all_fields=True)
    run = world_fields(world, sim)
    gt = invert_transform(sim.poses[0])[None] @ sim.poses
    base = declared_sweep(world, PlanodomConfig())
    option = declared_sweep(world, config_with(args.set))
    runs = {}
    for name, config in (("default", base), ("option", option)):
        runs[name] = run_odometry(run, config)
        summary(name, runs[name], gt, args.at)
        exact = run_odometry(run, config, extractor=exact_extractor(sim, run))
        summary(name + " exact", exact, gt, args.at)
    for name, odo in runs.items():
        census(sim, odo, name)
    steps = range(args.steps[0], args.steps[1] + 1)
    step_rows(sim, run, runs["option"], runs["option"].config or option, steps)
    plane_rows(sim, run, {"default": base, "option": option}, steps, runs["option"])


if __name__ == "__main__":
    main()
