"""Where ``odometry.turn_trend_retry`` acts in a run, against the truth (issue 11, TURN244).

Runs one 2D-rig world (``planodom experiment generalisation``'s) with the option on and,
for each epoch where the trend was tried, prints the prediction's and the trend's yaw-rate
error against the true mean twist over the epoch's points (deg/s), the status and planes
of both extractions, and which first extraction the epoch kept (``trend``, ``pred`` or
``none``, the last the epoch deskewed without a twist).

    uv run python experiments/turn_trend_census.py --world 244 --noise 0.006
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np
from builtin_scenes import config_with
from turn_lag import centre_twist

import planodom.odometry.odometry as odo_mod
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields

ROWS: list[dict[str, Any]] = []


def instrument() -> None:
    """Record, for every epoch whose trend was tried, the first extractions and the kept."""
    real_register = odo_mod.register_deskewed
    real_scan = odo_mod.PlaneOdometry._estimate_scan
    state: dict[str, Any] = {}

    def estimate_scan(self: Any, scan: Any, *a: Any, **k: Any) -> Any:
        state["k"] = len(self.poses)
        return real_scan(self, scan, *a, **k)

    def register(predicted: Any, dt: float, estimate: Any, *a: Any, **k: Any) -> Any:
        trend = a[5] if len(a) > 5 else None  # (refresh, config, previous, held, damped, trend)
        got: dict[str, Any] = {}

        def labelled(twist: Any, source: Any = None) -> Any:
            out = estimate(twist) if source is None else estimate(twist, source)
            if source is None:
                kind = "none" if twist is None else "trend" if twist is trend else "pred"
                got.setdefault(kind, out)
            else:
                got.setdefault("refined", source)
            return out

        best = real_register(predicted, dt, labelled, *a, **k)
        if "trend" in got:
            first = got.get("refined", best)
            kept = next((kind for kind in ("trend", "pred", "none")
                         if got.get(kind) is first), "?")  # fmt: skip
            ROWS.append({"k": state["k"], "pred": predicted, "trend": trend, "got": got,
                         "kept": kept, "final": best})  # fmt: skip
        return best

    odo_mod.register_deskewed = register
    odo_mod.PlaneOdometry._estimate_scan = estimate_scan  # type: ignore[method-assign]


def _fmt(est: Any) -> str:
    if est is None:
        return "  -     "
    return f"{est.relative.status.name[:5]:5s} {len(est.planes):2d}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--world", type=int, required=True)
    ap.add_argument("--noise", type=float, default=0.006)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    config = config_with(["odometry.turn_trend_retry=true", *args.set])
    world = world_for(args.world)
    sim = simulate_world(world, args.noise, n_epochs=args.epochs, all_fields=True)
    source, config = world_fields(world, sim), declared_sweep(world, config)
    instrument()
    run_odometry(source, config, None)
    print("epoch  true yaw  pred err  trend err | pred        trend       none      | kept  final")
    for r in ROWS:
        yaw = np.degrees(centre_twist(sim, r["k"])[2])
        pe = np.degrees(r["pred"][2]) - yaw
        te = np.degrees(r["trend"][2]) - yaw
        g = r["got"]
        print(f"{r['k']:5d}  {yaw:8.2f}  {pe:+8.2f}  {te:+9.2f} | {_fmt(g.get('pred'))}  "
              f"{_fmt(g.get('trend'))}  {_fmt(g.get('none'))} | {r['kept']:5s} "
              f"{_fmt(r['final'])}")  # fmt: skip
    kept = sum(r["kept"] == "trend" for r in ROWS)
    closer = sum(abs(r["trend"][2] - c) < abs(r["pred"][2] - c)
                 for r in ROWS for c in [centre_twist(sim, r["k"])[2]])  # fmt: skip
    print(f"tried {len(ROWS)}, kept {kept}, trend closer to the truth than the prediction {closer}")


if __name__ == "__main__":
    main()
