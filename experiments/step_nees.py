"""How well the odometry's steps state their own error: per-step NEES against the truth
(issues 11 and 14, DESKEWCOV).

Each 2D-rig world of ``--first-world`` .. ``+ --worlds`` (even indices; as ``planodom
experiment generalisation`` runs it: ``world_for``, ``declared_sweep``) is run at each
``--noise`` with the default config and with the ``--set`` overrides, in this process. Per
resolved step (``RelativePose`` from its reference epoch, OK or degenerate, with a finite
covariance) its 5-DoF error against the true relative pose (``pose5_error``: rotation
vector, x, y) is whitened by the step's stated (roll, pitch, yaw, x, y) covariance mapped
to the rotation vector (as the smoothing's between factors take it, without their
floors): NEES5 for OK steps (chi2 with 5 DoF: mean 5, 5 % above 11.07 when the
covariance is right), NEES3 of the rotation for both kinds (mean 3, 5 % above 7.81), and
the normalised yaw error ``e_yaw / sigma_yaw`` (rms 1). Summaries per noise and config:
mean and median, the share above the 95 % quantile, over all steps of all worlds.

``--coherent`` (a probe; needs the planes' Jacobians, ``extraction.deskew_jacobian``):
also NEES5 with both epochs' deskewing error added to the stated covariance as one twist
error per epoch shared by its planes (not one per plane), the odometry's estimate left
as it is: ``M_a Q_a M_a^T + M_b Q_b M_b^T`` with ``M`` the change of the step fitted to
its associated plane pairs when an epoch's planes move by their Jacobians
(:func:`planodom.smoothing.relative_deskew.pair_fit_changes`, as NEES6) and ``Q =
span^2 Sigma``, ``Sigma`` from the run's rms change of the twist between successive OK
steps (noise in, the whole run's; as ``plane_deskew_noise: change`` reads it), mapped to
(rotation vector, x, y) to first order at one step's small rotation. Epochs not deskewed
or whose planes were extracted again later (superseded) add nothing.

    uv run python experiments/step_nees.py --first-world 140 --worlds 20 \
        --noise 0.006 0.02 --epochs 150 --set odometry.plane_deskew_noise=twist
"""

from __future__ import annotations

import argparse
import csv

import numpy as np
from builtin_scenes import config_with
from scipy.stats import chi2

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.geometry import invert_transform, rpy_from_rotation
from planodom.odometry import Status, run_odometry
from planodom.odometry.plane_deskew import epoch_span, twist_covariance
from planodom.se3 import se3_log
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.noise import rpy_to_rotation_vector
from planodom.smoothing.relative_deskew import pair_fit_changes
from planodom_factors.pose5 import pose5_error


def run_change(odo) -> np.ndarray:  # noqa: ANN001
    """(6, 6) twist error covariance (rad/s, m/s) from the rms change of the twist between
    successive OK steps over the run (three axes each, as ``twist_covariance`` reads it)."""
    twists = {}
    for k, r in enumerate(odo.results):
        if r is not None and r.status is Status.OK and r.curr == r.prev + 1:
            dt = float(odo.times[k] - odo.times[k - 1])
            twists[k] = se3_log(np.asarray(r.T_prev_curr)) / dt
    d = np.array([twists[k] - twists[k - 1] for k in twists if k - 1 in twists])
    if len(d) == 0:
        return np.zeros((6, 6))
    ms = np.array([np.mean(np.sum(d[:, :3] ** 2, 1)), np.mean(np.sum(d[:, 3:] ** 2, 1))])
    return twist_covariance((float(np.sqrt(ms[0])), float(np.sqrt(ms[1]))))


def coherent_term(odo, run, r, sigma: np.ndarray) -> np.ndarray:  # noqa: ANN001
    """(5, 5) both epochs' shared deskewing error of step ``r`` (module docstring)."""
    if r.prev in odo.superseded or r.curr in odo.superseded or len(r.associations) == 0:
        return np.zeros((5, 5))
    T = np.asarray(r.T_prev_curr)
    ends = pair_fit_changes(T, odo.planes[r.prev], odo.planes[r.curr], r.associations)
    A = np.zeros((5, 6))
    A[:3, :3] = np.eye(3)
    A[3:, 3:] = T[:2, :3]  # right tangent's translation into frame prev's x, y
    out = np.zeros((5, 5))
    for k, M in zip((r.prev, r.curr), ends, strict=True):
        twist = odo.results[k].deskew_twist if odo.results[k] is not None else None
        if M is None or twist is None:
            continue
        span = epoch_span(run[k])
        AM = A @ M
        out += span**2 * AM @ sigma @ AM.T
    return out


def step_rows(
    world: int, noise: float, epochs: int, config: PlanodomConfig, coherent: bool = False
) -> list[dict]:
    """One row per resolved step with a finite covariance of one run."""
    w = world_for(world)
    full = simulate_world(w, noise, n_epochs=epochs, all_fields=True)
    run = world_fields(w, full)
    odo = run_odometry(run, declared_sweep(w, config))
    gt = invert_transform(full.poses[0])[None] @ full.poses
    sigma = run_change(odo) if coherent else None
    rows = []
    for k, r in enumerate(odo.results):
        if r is None or r.status is Status.UNRESOLVED or r.covariance is None:
            continue
        cov = np.asarray(r.covariance, dtype=float).reshape(5, 5)
        if not np.all(np.isfinite(cov)):
            continue
        J = np.eye(5)
        J[:3, :3] = rpy_to_rotation_vector(rpy_from_rotation(r.T_prev_curr[:3, :3]))
        P = J @ (0.5 * (cov + cov.T)) @ J.T
        e, _, _ = pose5_error(np.asarray(r.T_prev_curr), gt[r.prev], gt[r.curr])
        ok = r.status is Status.OK
        nees5 = float(e @ np.linalg.solve(P, e)) if ok else np.nan
        coh = np.nan
        if ok and sigma is not None:
            Pc = P + coherent_term(odo, run, r, sigma)
            coh = float(e @ np.linalg.solve(Pc, e))
        rows.append(
            {
                "world": world, "noise_m": noise, "epoch": k, "status": str(r.status),
                "nees5": nees5, "nees3": float(e[:3] @ np.linalg.solve(P[:3, :3], e[:3])),
                "nees5_coherent": coh,
                "z_yaw": float(e[2] / np.sqrt(P[2, 2])),
                "yaw_err_deg": float(np.degrees(e[2])),
                "yaw_sigma_deg": float(np.degrees(np.sqrt(P[2, 2]))),
            }
        )  # fmt: skip
    return rows


def summary(rows: list[dict]) -> str:
    """One line: NEES5 of OK steps, NEES3 of all, yaw z rms (mean, median, share > 95 %)."""
    n5 = np.array([r["nees5"] for r in rows if np.isfinite(r["nees5"])])
    n3 = np.array([r["nees3"] for r in rows])
    z = np.array([r["z_yaw"] for r in rows])
    q5, q3 = chi2.ppf(0.95, 5), chi2.ppf(0.95, 3)
    sig = np.array([r["yaw_sigma_deg"] for r in rows])
    line = (
        f"OK {len(n5)}: NEES5 mean {n5.mean():.3g} median {np.median(n5):.3g} "
        f">95% {np.mean(n5 > q5):.3f} | all {len(n3)}: NEES3 mean {n3.mean():.3g} "
        f"median {np.median(n3):.3g} >95% {np.mean(n3 > q3):.3f} | yaw z rms "
        f"{np.sqrt(np.mean(z**2)):.3g}, |z| > 2: {np.mean(np.abs(z) > 2):.3f} | yaw sigma "
        f"median {np.median(sig):.3g} deg, 95th pct {np.percentile(sig, 95):.3g}"
    )
    c5 = np.array([r["nees5_coherent"] for r in rows if np.isfinite(r["nees5_coherent"])])
    if len(c5):
        line += (
            f" | coherent NEES5 mean {c5.mean():.3g} median {np.median(c5):.3g} "
            f">95% {np.mean(c5 > q5):.3f}"
        )
    return line


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first-world", type=int, default=140)
    parser.add_argument("--worlds", type=int, default=20)
    parser.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    parser.add_argument("--epochs", type=int, default=150)
    parser.add_argument(
        "--set", nargs="*", action="extend", default=[], help="the option's overrides key=value"
    )
    parser.add_argument("--out", help="CSV of every step (both configs)")
    parser.add_argument("--coherent", action="store_true", help="the shared-error probe")
    args = parser.parse_args()
    worlds = [i for i in range(args.first_world, args.first_world + args.worlds) if i % 2 == 0]
    configs = {"default": PlanodomConfig(), "option": config_with(args.set)}
    all_rows = []
    for noise in args.noise:
        for name, config in configs.items():
            rows = []
            for world in worlds:
                coherent = args.coherent and config.extraction.deskew_jacobian
                steps = step_rows(world, noise, args.epochs, config, coherent)
                rows += [{"config": name, **r} for r in steps]
            print(f"{noise * 1000:g} mm {name}: {summary(rows)}", flush=True)
            all_rows += rows
    if args.out and all_rows:
        with open(args.out, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(all_rows[0]))
            writer.writeheader()
            writer.writerows(all_rows)


if __name__ == "__main__":
    main()
