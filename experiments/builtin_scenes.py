"""The built-in scenes' odometry against the truth (issue 11: no figure gets worse).

Per built-in scene (``planodom run --scenario`` defaults: isoclinal rig, continuous
motion, seed 0, one lap) and range noise (metres, or a preset such as ``lms221``), the
odometry of ``planodom run`` (default config, or ``--set KEY=VALUE`` overrides) as one
CSV row: ATE xy and 3-D (m, aligned at the origin), ATE xy over the start (epochs 0 to
the first measured step) and ATE xy / 3-D after it (from that epoch on, aligned there:
what the start's poses do not touch), the steps' rotation / xy rms (deg, cm) and mean x
error (mm per step, + too far forward), unresolved and degenerate epochs, the statuses
of steps 1-5, the first measured step (status OK; where ``odometry.start_refresh``'s
start closes; -1 none) and CPU seconds; and ATE xy aligned by a rigid fit (``se3``).
With ``--draws`` each scene and noise is run once per noise draw (the same world and
route; a row each, the noise column naming the draw). With ``--pair`` each scene is run
with ``odometry.start_refresh`` on and off, both rows split at the later first measured
step, with a note on stderr (:func:`pair_rows`).
With ``--detail N`` it also prints, for epochs 0..N-1, the status, the twist the
epoch's planes were last extracted with against the true one at the epoch (rad/s, m/s),
the pose's error (mrad, cm; the first pose is the frame) and the planes' error against
their true surfaces (median mrad, cm).

    uv run python experiments/builtin_scenes.py --scenes random-outdoor --noise lms221
    uv run python experiments/builtin_scenes.py --scenes urban-canyon --noise 0.02 \\
        --set odometry.start_refresh=false --detail 12
    uv run python experiments/builtin_scenes.py --scenes random --noise 0.02 --pair
    uv run python experiments/builtin_scenes.py --scenes random-outdoor --noise 0.02 \
        --draws 0 1 2 3 4    # the same world with five draws of its range noise
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from first_epochs import plane_errors  # the same check of planes against their surfaces

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, se3_log
from planodom.metrics import aligned, ate, per_epoch_errors, pose_errors, relative_motions
from planodom.odometry import run_odometry

SCENES = ("paper-loop", "urban-canyon", "random", "random-outdoor", "random-indoor")


def true_twist(sim, k: int) -> np.ndarray:  # noqa: ANN001
    """(6,) the constant twist (rad/s, m/s) that maps epoch ``k``'s earliest point time to
    its reference time along the true trajectory: what deskewing it exactly would take."""
    t = sim.scans[k].t
    h = float(np.min(t)) if t is not None and len(t) and np.min(t) < 0 else -0.05
    t_k = float(sim.times[k])
    T = sim.trajectory.poses(np.array([t_k, t_k + h]))
    return se3_log(invert_transform(T[0]) @ T[1]) / h


def start_closed(run) -> int:  # noqa: ANN001
    """The first epoch whose step is measured (status OK), -1 none."""
    return next((k for k, s in enumerate(run.statuses) if s == "ok"), -1)


def simulated(scene: str, noise: str, draw: int = 0):  # noqa: ANN201
    """The scene as ``planodom run --scenario`` simulates it, and its true poses (E, 4, 4)
    in the first pose's frame; ``draw`` > 0: the same scene and route with the range
    noise drawn with seed ``draw`` (0: the scene's own draw)."""
    from planodom.cli.common import simulate_scene

    sim = simulate_scene(scene, "isoclinal", noise, 0, None, "continuous", noise_seed=draw or None)
    return sim, invert_transform(sim.poses[0])[None] @ sim.poses


def print_detail(sim, run, gt: np.ndarray, n: int) -> None:  # noqa: ANN001
    """Per-epoch rows of epochs 0..n-1 to stderr (module docstring)."""
    xi = pose_errors(run.poses, gt)
    fmt = lambda v: "none" if v is None else " ".join(f"{x:+.3f}" for x in v)  # noqa: E731
    for k in range(min(n, len(run.poses))):
        r = run.results[k]
        used = r.deskew_twist if r is not None else None
        a, o = plane_errors(run.planes[k], sim.poses[k], sim.scene)
        print(f"  {k:3d} {run.statuses[k][:5]:5s} used [{fmt(used)}] true "
              f"[{fmt(true_twist(sim, k))}] pose {np.linalg.norm(xi[k, :3]) * 1e3:6.2f} mrad "
              f"{np.linalg.norm(xi[k, 3:]) * 100:6.2f} cm planes {a:6.2f} mrad {o:6.2f} cm",
              file=sys.stderr)  # fmt: skip


def row(scene: str, noise: str, run, gt: np.ndarray, cpu: float, c: int | None = None) -> dict:  # noqa: ANN001
    """The CSV row of ``run`` (module docstring); ``c``: the epoch the start's and after's
    ATE split at (default the run's first measured step)."""
    err = per_epoch_errors(relative_motions(run.poses), relative_motions(gt))
    rot = np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))
    xy = np.hypot(err["x"], err["y"])
    c = max(start_closed(run), 0) if c is None else c
    return {
        "scene": scene, "noise": noise, "epochs": len(run.poses),
        "ate_xy_m": ate(run.poses, gt, align="origin", xy_only=True)["rmse"],
        "ate_3d_m": ate(run.poses, gt, align="origin")["rmse"],
        "ate_xy_start_m": ate(run.poses[: c + 1], gt[: c + 1], "origin", xy_only=True)["rmse"],
        "ate_xy_after_m": ate(run.poses[c:], gt[c:], "origin", xy_only=True)["rmse"],
        "ate_3d_after_m": ate(run.poses[c:], gt[c:], "origin")["rmse"],
        "ate_xy_se3_m": ate(run.poses, gt, align="se3", xy_only=True)["rmse"],
        "rot_rms_deg": float(np.sqrt(np.mean(rot**2))),
        "xy_rms_cm": float(np.sqrt(np.mean(xy**2)) * 100),
        "x_bias_mm": float(np.mean(err["x"]) * 1000),
        "unresolved": run.n_unresolved, "degenerate": run.n_degenerate,
        "status1_5": " ".join(s[:3] for s in run.statuses[1:6]),
        "first_ok": start_closed(run), "cpu_s": round(cpu, 1),
    }  # fmt: skip


def timed_run(sim, config: PlanodomConfig):  # noqa: ANN001, ANN201
    c0 = time.process_time()
    run = run_odometry(sim, config, sim.rig)
    return run, time.process_time() - c0


def pair_rows(scene: str, noise: str, config: PlanodomConfig) -> list[dict]:
    """``odometry.start_refresh`` on and off on one scene: their rows split at the later
    first measured step ``c``, and a note (stderr) of the largest difference of their
    steps after ``c``, the off run's position at ``c`` minus the on run's (xy, m) and the
    on run's mean position error after ``c`` along that offset (m)."""
    sim, gt = simulated(scene, noise)
    runs = {on: timed_run(sim, config.updated({"odometry.start_refresh": on}, source="pair"))
            for on in (True, False)}  # fmt: skip
    c = max(max(start_closed(run), 0) for run, _ in runs.values())
    (P_on, _), (P_off, _) = ((r.poses, t) for r, t in runs.values())
    steps = lambda P: relative_motions(P[c:])  # noqa: E731
    e_on = aligned(P_on, gt)[:, :2, 3] - gt[:, :2, 3]
    offset = (aligned(P_off, gt)[c, :2, 3] - gt[c, :2, 3]) - e_on[c]
    along = float(e_on[c:].mean(axis=0) @ offset / max(np.linalg.norm(offset), 1e-12))
    print(f"# {scene} {noise}: after epoch {c} steps differ by "
          f"{np.abs(steps(P_on) - steps(P_off)).max():.2g}; off - on at {c}: "
          f"{np.round(offset, 3)} m; on's mean error after along it {along:+.3f} m",
          file=sys.stderr)  # fmt: skip
    return [
        row(scene, f"{noise} {'on' if on else 'off'}", r, gt, t, c) for on, (r, t) in runs.items()
    ]


def config_with(sets: list[str]) -> PlanodomConfig:
    """The default configuration with the ``key=value`` overrides ``sets`` (dotted keys;
    ``true`` / ``false`` read as booleans, other values as the config reads them)."""
    changes: dict[str, object] = {}
    for item in sets:
        key, value = item.split("=", 1)
        changes[key] = {"true": True, "false": False}.get(value.lower(), value)
    return PlanodomConfig().updated(changes, source="cli") if changes else PlanodomConfig()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--noise", nargs="+", default=["0", "0.006", "0.02"],
                        help="metres or a preset (lms221)")  # fmt: skip
    parser.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    parser.add_argument("--detail", type=int, default=0, help="per-epoch rows of the first N")
    parser.add_argument("--draws", type=int, nargs="+", default=[0],
                        help="noise seeds (0: the scene's own); a row per draw")  # fmt: skip
    parser.add_argument("--pair", action="store_true",
                        help="start_refresh on and off, split at the same epoch")  # fmt: skip
    args = parser.parse_args()
    config = config_with(args.set)
    header = False
    for scene in args.scenes:
        for noise in args.noise:
            if args.pair:
                rows = pair_rows(scene, noise, config)
            else:
                rows = []
                for draw in args.draws:
                    sim, gt = simulated(scene, noise, draw)
                    run, cpu = timed_run(sim, config)
                    if args.detail:
                        print_detail(sim, run, gt, args.detail)
                    label = noise if draw == 0 else f"{noise} draw {draw}"
                    rows.append(row(scene, label, run, gt, cpu))
            for out in rows:
                if not header:
                    print(",".join(out), flush=True)
                    header = True
                print(",".join(f"{v:.4f}" if isinstance(v, float) else str(v)
                               for v in out.values()), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
