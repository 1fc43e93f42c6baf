"""Why the 2D rig's streaming odometry extracts an epoch more than once, and what it buys.

Per epoch, each extraction + estimate of :func:`planodom.odometry.deskew.register_deskewed`
is labelled by why it ran: ``first`` (deskewed with the prediction), ``alternative`` (the
first one suspect: without a twist, the trend, the held twist), ``refine1`` / ``refine2``
(the epoch's own twist, ``deskew_iterations``), and inside any of them ``widened`` (the
tight extraction lost, :func:`planodom.odometry.twist_sigma.widened_if_lost`). Extractions
of a reference epoch (refresh, the first epoch's rounds) are counted apart. For each
refinement pass: whether it was kept, whether it changed the status, and how far its step
moved from the estimate it replaced (rotation deg, translation mm), and the largest
displacement its twist change makes on the epoch's points (``max |dw x p + dv| |t|``, mm).

``--change-gate`` runs with ``odometry.deskew_change_gate`` on. Worlds 0-18 even at 6 mm and
2 cm (docs/RESULTS.md, RIG2DPASS) take about 50 s of CPU:

    uv run python experiments/pass_census.py --worlds 0 2 4 6 8 10 12 14 16 18
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
from collections import Counter  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import planodom.odometry.deskew as deskew_mod  # noqa: E402
import planodom.odometry.odometry as odo_mod  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.geometry import invert_transform, se3_log  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.odometry.twist_sigma import step_sigma  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

STATE: dict[str, Any] = {"label": "other", "scan": None}
COUNTS: Counter[str] = Counter()
REFINES: list[dict[str, float]] = []


def _step_change(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Rotation (deg) and translation (mm) of ``inv(a) @ b``."""
    d = se3_log(invert_transform(a) @ b)
    return float(np.degrees(np.linalg.norm(d[:3]))), float(1e3 * np.linalg.norm(d[3:]))


def _displacement_mm(scan: Any, new: np.ndarray, used: np.ndarray | None) -> float:
    """Largest ``|dw x p + dv| |t|`` over the scan's points, mm (first order)."""
    d = new - (np.zeros(6) if used is None else used)
    p, t = np.asarray(scan.points), np.asarray(scan.t)
    moved = np.cross(d[:3], p) + d[3:]
    return float(1e3 * np.max(np.linalg.norm(moved, axis=1) * np.abs(t)))


def _twist_change(new: np.ndarray, source: Any, dt: float) -> dict[str, float]:
    """The refined twist's change from the one used, and the own twist's sigma
    (:func:`planodom.odometry.twist_sigma.step_sigma`): deg/s and m/s."""
    used = np.zeros(6) if source.twist is None else source.twist
    sigma = step_sigma(source.relative, dt)
    return {
        "drate": float(np.degrees(np.linalg.norm(new[:3] - used[:3]))),
        "dspeed": float(np.linalg.norm(new[3:] - used[3:])),
        "rate_sigma": float(np.degrees(sigma[0])), "speed_sigma": float(sigma[1]),
    }  # fmt: skip


def instrument() -> None:
    real_register = deskew_mod.register_deskewed
    real_first = deskew_mod._first_estimate
    real_widened = odo_mod.widened_if_lost
    real_extract = odo_mod.PlaneOdometry._extract
    real_estimate_scan = odo_mod.PlaneOdometry._estimate_scan

    def estimate_scan(self: Any, scan: Any, *a: Any, **k: Any) -> Any:
        STATE["scan"] = scan
        return real_estimate_scan(self, scan, *a, **k)

    def extract(self: Any, *a: Any, **k: Any) -> Any:
        COUNTS["extractions"] += 1
        COUNTS[f"extract:{STATE['label']}"] += 1
        return real_extract(self, *a, **k)

    def widened(estimate: Any, *a: Any, **k: Any) -> Any:
        label = STATE["label"]
        calls = [0]

        def counted(sigma: Any) -> Any:
            calls[0] += 1
            if calls[0] == 2:
                STATE["label"] = f"{label}+widened"
                STATE["wide"] = estimate(sigma)
                return STATE["wide"]
            return estimate(sigma)

        out = real_widened(counted, *a, **k)
        STATE["label"] = label
        if calls[0] == 2:
            COUNTS[f"widened kept:{label}"] += int(out is STATE.get("wide"))
        return out

    def first(predicted: Any, dt: Any, estimate: Any, *a: Any) -> Any:
        calls = [0]

        def labelled(twist: Any, source: Any = None) -> Any:
            calls[0] += 1
            STATE["label"] = "first" if calls[0] == 1 else "alternative"
            got = estimate(twist) if source is None else estimate(twist, source)
            if calls[0] == 1:
                STATE["first_out"] = got
            return got

        out = real_first(predicted, dt, labelled, *a)
        if calls[0] > 1:
            COUNTS["alternative kept"] += int(out is not STATE["first_out"])
        STATE["label"] = "reference refresh"
        return out

    def register(predicted: Any, dt: Any, estimate: Any, *a: Any, **k: Any) -> Any:
        refines: list[tuple[Any, Any, dict[str, float]]] = []

        def labelled(twist: Any, source: Any = None) -> Any:
            if source is None:
                return estimate(twist)
            STATE["label"] = f"refine{len(refines) + 1}"
            again = estimate(twist, source)
            rot, mm = _step_change(source.step, again.step)
            rec = {
                "rot_deg": rot, "mm": mm,
                "status_change": float(again.relative.status is not source.relative.status),
                "better": float(again.relative.status.rank > source.relative.status.rank),
                "moved_mm": _displacement_mm(STATE["scan"], twist, source.twist),
                "index": float(len(refines) + 1),
                **_twist_change(twist, source, dt),
            }  # fmt: skip
            refines.append((source, again, rec))
            return again

        STATE["label"] = "first"
        best = real_register(predicted, dt, labelled, *a, **k)
        for _, again, rec in refines:
            rec["kept"] = float(again is best or any(again is s for s, _, _ in refines))
            REFINES.append(rec)
        COUNTS["epochs"] += 1
        STATE["label"] = "reference (first-epoch rounds)"
        return best

    deskew_mod._first_estimate = first  # type: ignore[assignment]
    odo_mod.register_deskewed = register
    odo_mod.widened_if_lost = widened
    odo_mod.PlaneOdometry._extract = extract  # type: ignore[method-assign]
    odo_mod.PlaneOdometry._estimate_scan = estimate_scan  # type: ignore[method-assign]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[0, 2, 4])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--change-gate", action="store_true", help="odometry.deskew_change_gate on")
    args = ap.parse_args()
    instrument()
    base = PlanodomConfig()
    if args.change_gate:
        base = base.updated({"odometry.deskew_change_gate": True}, source="pass_census")
    for noise in args.noise:
        COUNTS.clear()
        REFINES.clear()
        STATE["noise"] = noise
        for w in args.worlds:
            world = world_for(w)
            cfg = declared_sweep(world, base)
            sim = simulate_world(world, noise, n_epochs=args.epochs, all_fields=True)
            run_odometry(world_fields(world, sim), cfg)
        _print(noise, args.epochs * len(args.worlds))


def _print(noise: float, epochs: int) -> None:
    print(f"--- noise {noise * 1e3:g} mm, {epochs} epochs")
    for key in sorted(COUNTS):
        print(f"  {key:32s} {COUNTS[key]:6d}  {COUNTS[key] / epochs:5.2f}/epoch")
    if not REFINES:
        return
    every = {k: np.array([x[k] for x in REFINES]) for k in REFINES[0]}
    for i in (1, 2):
        sel = every["index"] == i
        _print_refines({k: v[sel] for k, v in every.items()}, noise, i)


def _print_refines(r: dict[str, np.ndarray], noise: float, i: int) -> None:
    changed, better = int(r["status_change"].sum()), int(r["better"].sum())
    print(
        f"  refine{i}: passes {len(r['kept'])}, kept {int(r['kept'].sum())}, "
        f"status changed {changed} (better {better})"
    )
    for q in (50, 90, 99):
        print(f"    p{q}: step moved {np.percentile(r['rot_deg'], q):.4f} deg "
              f"{np.percentile(r['mm'], q):.2f} mm; points moved "
              f"{np.percentile(r['moved_mm'], q):.2f} mm")  # fmt: skip
    for key in ("drate", "rate_sigma", "dspeed", "speed_sigma"):
        v = r[key][np.isfinite(r[key])]
        print(
            f"    {key}: p10/50/90 " + " ".join(f"{np.percentile(v, q):.3f}" for q in (10, 50, 90))
        )
    for frac in (0.25, 0.5, 1.0):
        small = r["moved_mm"] < frac * noise * 1e3
        print(f"    points moved < {frac:g} sigma: {int(small.sum())} passes, "
              f"of which status changed {int(r['status_change'][small].sum())}, step moved "
              f"max {r['rot_deg'][small].max(initial=0):.4f} deg "
              f"{r['mm'][small].max(initial=0):.2f} mm")  # fmt: skip


if __name__ == "__main__":
    main()
