"""The 2D rig's prior-free retry (``odometry.retry_without_prior``): what it wins, what it costs.

Each 2D-rig world's run is simulated once; planodom's default odometry runs on it with every
solve of :func:`planodom.odometry.solver.estimate_relative_pose` recorded: for each retry
(a solve without the prior's bounds after a solve under them that was not OK) the first
and the retry's status, their LDA candidates, the prior's step and how far the retry's pose
lies from it, whether the previous epoch was unresolved (a bridged prior), and the retry's
CPU time. A retry that does not improve the status is discarded by the solver, so a run
whose retries never win is bit-identical with the retry off or restricted (``--policy``):
only runs with a winning retry are run again, with each policy, and with the oracle (its
longest gap). Prints one line per run and policy and, with ``--retries CSV``, writes every
retry. ``--check`` runs every policy on every run (to prove the identity).

    uv run python experiments/retry_census.py --worlds 100 102 --noise 0.006 0.02 \\
        --policy off unresolved --retries retries.csv
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import planodom.odometry.odometry as odometry_module  # noqa: E402
import planodom.odometry.solver as solver  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import MethodRun, _metrics, world_for  # noqa: E402
from planodom.geometry import invert_transform  # noqa: E402
from planodom.odometry import Status, run_odometry  # noqa: E402
from planodom.oracle import run_oracle  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

#: policy name -> whether a retry may replace the first solve, given the first status and
#: whether the previous epoch was unresolved (the prior then bridged, not measured).
POLICIES: dict[str, Callable[[Status, bool], bool]] = {
    "default": lambda first, bridged: True,
    "off": lambda first, bridged: False,
    "unresolved": lambda first, bridged: first is Status.UNRESOLVED,
    "unresolved-or-bridged": lambda first, bridged: first is Status.UNRESOLVED or bridged,
}
#: policies that decide on the candidates: the retry kept only if the prior-free LDA
#: admits more candidates than the prior's (a retry after an unresolved solve then too)
MORE_CANDIDATES = "more-candidates"


class Recorder:
    """Wraps the solver's passes; records the retries and applies a policy to them."""

    def __init__(self) -> None:
        self.policy: Callable[[Status, bool], bool] | None = POLICIES["default"]
        self.retries: list[dict[str, Any]] = []
        self.first: Any = None
        self.epoch = -1
        self.bridged = False
        self.cpu = 0.0
        self._solve = solver._solve
        self._register = odometry_module.PlaneOdometry.register_epoch
        solver._solve = self.solve  # type: ignore[assignment]
        rec = self

        def register(odo: Any, *args: Any, **kwargs: Any) -> Any:
            rec.epoch = len(odo.poses)
            rec.bridged = getattr(odo.last_relative, "status", None) is Status.UNRESOLVED
            return rec._register(odo, *args, **kwargs)

        odometry_module.PlaneOdometry.register_epoch = register  # type: ignore[method-assign,assignment]

    def solve(self, prev: Any, curr: Any, cfg: Any, prior: Any, bound: bool, *rest: Any) -> Any:
        if bound or prior is None:  # a first solve
            self.first = self._solve(prev, curr, cfg, prior, bound, *rest)
            return self.first
        c0 = time.process_time()
        free: Any = self._solve(prev, curr, cfg, prior, bound, *rest)
        spent = time.process_time() - c0
        self.cpu += spent
        first = self.first
        won = free.status.rank > first.status.rank
        dT = invert_transform(prior) @ free.T_prev_curr
        angle = np.degrees(np.arccos(np.clip((np.trace(dT[:3, :3]) - 1) / 2, -1, 1)))
        self.retries.append({
            "epoch": self.epoch, "bridged": self.bridged, "first": first.status.value,
            "retry": free.status.value, "won": won, "cpu_ms": 1e3 * spent,
            "lda_first": len(first.diagnostics.lda), "lda_retry": len(free.diagnostics.lda),
            "prior_step_m": float(np.linalg.norm(prior[:2, 3])),
            "off_prior_m": float(np.linalg.norm(dT[:2, 3])), "off_prior_deg": float(angle),
        })  # fmt: skip
        more = len(free.diagnostics.lda) > len(first.diagnostics.lda)
        if won and not (more if self.policy is None else self.policy(first.status, self.bridged)):
            return first  # the policy refuses it: the solver keeps the first (same rank)
        return free


def run_once(rec: Recorder, run: Any, cfg: PlanodomConfig, policy: str) -> tuple[Any, float]:
    """The odometry under ``policy``; its process time, s."""
    rec.policy, rec.retries, rec.cpu = POLICIES.get(policy), [], 0.0
    c0 = time.process_time()
    odo = run_odometry(run, cfg)
    return odo, time.process_time() - c0


def metrics_of(world: Any, noise: float, odo: Any, gt: np.ndarray, oracle: Any) -> dict:
    mr = MethodRun(world.seed, world.kind, "rig2d", noise, "planodom", odo.poses,
                   list(odo.statuses), 1.0, gt)  # fmt: skip
    return _metrics(mr, oracle)


def one_run(rec: Recorder, w: int, noise: float, epochs: int, policies: list[str],
            check: bool, rows: list[dict]) -> None:  # fmt: skip
    world = world_for(w)
    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    run = world_fields(world, full)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    cfg = PlanodomConfig()
    odo, cpu = run_once(rec, run, cfg, "default")
    retries = rec.retries
    wins = sum(r["won"] for r in retries)
    base = {"world": w, "noise_mm": noise * 1e3}
    for r in retries:
        rows.append(base | r)
    changed = wins > 0 or check
    oracle = None
    if changed:
        oracle = run_oracle(full.scans, full.times, world.trajectory, world.scene).statuses
    m = metrics_of(world, noise, odo, gt, oracle)
    _say(base, "default", m, cpu, len(retries), wins, rec.cpu)
    for policy in policies if changed else []:
        other, cpu2 = run_once(rec, run, cfg, policy)
        same = np.array_equal(other.poses, odo.poses) and other.statuses == odo.statuses
        _say(base, policy, metrics_of(world, noise, other, gt, oracle), cpu2, same=same)


def _say(base: dict, policy: str, m: dict, cpu: float, n: int = -1, wins: int = -1,
         retry_cpu: float = 0.0, same: bool | None = None) -> None:  # fmt: skip
    extra = f" retries {n} wins {wins} retry_cpu {100 * retry_cpu / cpu:.1f}%" if n >= 0 else ""
    extra += "" if same is None else f" identical {same}"
    print(f"world {base['world']} {base['noise_mm']:g} mm {policy:22s} ate {m['ate_xy_m']:.4f} "
          f"rot {m['rot_rms_deg']:.4f} xy {m['xy_rms_m']:.4f} unres {m['unresolved']:g} "
          f"degen {m['degenerate']:g} gap* {m['gap_oracle']:g} cpu {cpu:.2f}{extra}",
          flush=True)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", required=True)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    policies = [*sorted(POLICIES), MORE_CANDIDATES]
    ap.add_argument("--policy", nargs="*", default=["off"], choices=policies)
    ap.add_argument("--check", action="store_true", help="run every policy on every run")
    ap.add_argument("--retries", help="CSV of every retry")
    args = ap.parse_args()
    if any(w % 2 for w in args.worlds):
        raise SystemExit("the 2D rig's worlds are the even ones")
    rec, rows = Recorder(), []  # type: ignore[var-annotated]
    warm = world_for(args.worlds[0])  # untimed: the compiled kernels' loading
    run_odometry(world_fields(warm, simulate_world(warm, 0.0, n_epochs=3, all_fields=True)))
    for w in args.worlds:
        for noise in args.noise:
            one_run(rec, w, noise, args.epochs, args.policy, args.check, rows)
    if args.retries and rows:
        with open(args.retries, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)


if __name__ == "__main__":
    main()
