"""Per epoch, the twists the 2D rig's deskewing uses against the truth (PASSES2CM).

For each epoch of the streaming odometry (:func:`planodom.odometry.deskew.register_deskewed`)
this records the predicted twist (the first pass's), the twist of each refinement (the
epoch's own, ``deskew_iterations``) and which estimate was kept, and compares their angular
rates (deg/s) with the true mean twist over the epoch's points' time span, and each pass's
step rotation with the true step (deg). ``--iterations`` sets ``odometry.deskew_iterations``.

    uv run python experiments/refine_twist_truth.py --worlds 174 176 --noise 0.02
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import planodom.odometry.deskew as deskew_mod  # noqa: E402
import planodom.odometry.odometry as odo_mod  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.geometry import invert_transform, se3_log  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

STATE: dict[str, Any] = {"scan": None}
ROWS: list[dict[str, Any]] = []


def _rot_err_deg(step: np.ndarray, truth: np.ndarray) -> float:
    """Rotation angle (deg) of ``inv(truth) @ step``."""
    return float(np.degrees(np.linalg.norm(se3_log(invert_transform(truth) @ step)[:3])))


def _rot_vec_deg(step: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(3,) rotation vector (deg) of ``inv(truth) @ step``: the signed error."""
    return np.degrees(se3_log(invert_transform(truth) @ step)[:3])


def _rate(tw: np.ndarray | None) -> list[float] | None:
    return None if tw is None else [float(x) for x in np.degrees(np.asarray(tw)[:3])]


def instrument() -> None:
    real_register = deskew_mod.register_deskewed
    real_estimate_scan = odo_mod.PlaneOdometry._estimate_scan

    def estimate_scan(self: Any, scan: Any, *a: Any, **k: Any) -> Any:
        STATE["scan"] = scan
        return real_estimate_scan(self, scan, *a, **k)

    def register(predicted: Any, dt: Any, estimate: Any, *a: Any, **k: Any) -> Any:
        passes: list[Any] = []

        def labelled(twist: Any, source: Any = None) -> Any:
            got = estimate(twist) if source is None else estimate(twist, source)
            passes.append((source is not None, twist, got))
            return got

        best = real_register(predicted, dt, labelled, *a, **k)
        ROWS.append({"scan": STATE["scan"], "dt": dt, "predicted": predicted,
                     "passes": passes, "best": best})  # fmt: skip
        return best

    odo_mod.register_deskewed = register
    odo_mod.PlaneOdometry._estimate_scan = estimate_scan  # type: ignore[method-assign]


def true_twist(sim: Any, k: int, scan: Any) -> np.ndarray:
    """(6,) the true mean body twist over the scan's time span (rad/s, m/s)."""
    t = np.asarray(scan.t)
    a, b = sim.times[k] + float(t.min()), sim.times[k] + float(t.max())
    Ta, Tb = sim.trajectory.pose(a), sim.trajectory.pose(b)
    return se3_log(invert_transform(Ta) @ Tb) / (b - a)


def analyse(sim: Any) -> list[dict[str, Any]]:
    index = {id(s): i for i, s in enumerate(sim.scans)}
    out = []
    for row in ROWS:
        k = index.get(id(row["scan"]))
        if k is None or k == 0:
            continue
        truth = true_twist(sim, k, row["scan"])
        step_true = invert_transform(sim.poses[k - 1]) @ sim.poses[k]
        rec: dict[str, Any] = {"k": k, "true_rate": _rate(truth)}
        for name, tw in (("predicted", row["predicted"]),):
            rec[name] = _rate(tw)
        rec["passes"] = [
            {"refine": r, "rate": _rate(tw), "status": got.relative.status.name,
             "rot_err": _rot_err_deg(got.step, step_true), "kept": got is row["best"],
             "rate_err": None if tw is None
             else float(np.degrees(np.linalg.norm(np.asarray(tw)[:3] - truth[:3])))}
            for r, tw, got in row["passes"]
        ]  # fmt: skip
        rec["status"] = row["best"].relative.status.name
        rec["rot_err"] = _rot_err_deg(row["best"].step, step_true)
        rec["rot_vec"] = [float(x) for x in _rot_vec_deg(row["best"].step, step_true)]
        rec["refined"] = any(p["refine"] and p["kept"] for p in rec["passes"])
        out.append(rec)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[174, 176])
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--iterations", type=int, default=2)
    ap.add_argument("-o", "--output", default=None, help="JSON of the per-epoch records")
    args = ap.parse_args()
    instrument()
    base = PlanodomConfig().updated(
        {"odometry.deskew_iterations": args.iterations}, source="refine_twist_truth"
    )
    result = {}
    for w in args.worlds:
        ROWS.clear()
        world = world_for(w)
        sim = simulate_world(world, args.noise, n_epochs=args.epochs, all_fields=True)
        run_odometry(world_fields(world, sim), declared_sweep(world, base))
        result[w] = analyse(sim)
        _summary(w, result[w])
    if args.output:
        with open(args.output, "w") as f:
            json.dump(result, f)


def _paired(recs: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
    """Angular-rate errors (deg/s, norm of the 3-vector) of the first pass's twist and of
    the first refinement's, on the epochs that have both."""
    first, refined = [], []
    for r in recs:
        truth = np.array(r["true_rate"])
        f = [p for p in r["passes"] if not p["refine"] and p["rate"] is not None]
        g = [p for p in r["passes"] if p["refine"]]
        if f and g:
            first.append(np.linalg.norm(np.array(f[0]["rate"]) - truth))
            refined.append(np.linalg.norm(np.array(g[0]["rate"]) - truth))
    return np.array(first), np.array(refined)


def _summary(w: int, recs: list[dict[str, Any]]) -> None:
    first, refined = _paired(recs)
    lost = [r for r in recs if r["status"] == "UNRESOLVED"]
    by_refine = [
        r for r in lost
        if any(p["refine"] and p["kept"] for p in r["passes"])
        and any(p["status"] != "UNRESOLVED" for p in r["passes"])
    ]  # fmt: skip
    med = np.median(first) if len(first) else np.nan
    med_r = np.median(refined) if len(refined) else np.nan
    better = 100.0 * float(np.mean(refined < first)) if len(first) else np.nan
    print(f"world {w}: epochs {len(recs)}; rate error of the first pass / first refinement "
          f"(median, {len(first)} epochs) {med:.2f} / {med_r:.2f} deg/s, refinement closer "
          f"in {better:.0f} %; unresolved {len(lost)}, of them a kept refinement after a "
          f"resolved pass {len(by_refine)}")  # fmt: skip


if __name__ == "__main__":
    main()
