"""Why the deskewing twist lags a sharp turn, against the truth (issue 11, TURNLAG).

One 2D-rig world (``world_for``, as ``planodom experiment generalisation`` runs it) or a
built-in scene (``planodom run --scenario``'s simulation) is run with the default config
(or the ``--set`` overrides), every extraction the deskewing policy makes recorded
(:func:`planodom.odometry.deskew.register_deskewed`). Per epoch of ``--steps A B``:

- ``truth``: the true twist at the epoch's centre, the mean body twist over its points'
  time span (roll, pitch, yaw rate deg/s), and the true twist of the step into the epoch
  (its mean over the step: what the epoch's own twist is at best, centred half a step
  before the epoch's reference time);
- per extraction tried (``pred``: the predicted twist, ``none``, ``held``, ``trend``,
  ``own``: the refinement with the epoch's own twist): its yaw-rate error and roll/pitch
  rate error against the centre truth (deg/s), status, planes and distinct true surfaces
  (``p/s``), whether the ground is among them, and ``*`` on the one kept;
- ``own``: the epoch's own twist (of the kept first estimate) against the centre truth
  and against the true step twist (yaw, roll/pitch deg/s): the first is the lag plus the
  measurement's error, the second the measurement's error alone; and ``why``: why the
  refinement did not recover (``unresolved``: no own twist; ``tolerance``: its rate within
  ``deskew_rate_tolerance_deg_s`` of the twist used; ``worse``: the refinement's status
  was worse, dropped; ``kept``: refined and kept);
- probes, the epoch extracted again (against the same reference, nothing committed) with
  the true centre twist, the true step twist and the own twist's three rates led to the
  points' mean time along their change since the previous epoch's own (``p/s`` and
  status; the velocity the own twist's; ``why``'s "not deskewed, velocity unmeasured":
  kept without a twist and not OK, so not refined).

With ``--exact`` (a world only) nothing is run: each epoch of ``--steps`` is simulated
alone and extracted with true twists: the step's into the epoch before (a perfect
prediction), the step's into the epoch (a perfect own twist), that one with its yaw rate
led to the points' mean time along its change since the step before (``odometry.
deskew_rate_lead: yaw`` with exact rates) and the mean over the points (the truth), each
as yaw-rate error (deg/s) and planes / distinct true surfaces (``g``: with the ground).

    uv run python experiments/turn_lag.py --world 166 --noise 0.006 --steps 70 82
    uv run python experiments/turn_lag.py --world 166 --noise 0 0.006 --steps 72 78 --exact
    uv run python experiments/turn_lag.py --scene random-indoor --noise 0.02 --steps 488 502
"""

from __future__ import annotations

import argparse
from functools import partial
from typing import Any

import numpy as np
from builtin_scenes import config_with, simulated

import planodom.odometry.deskew as deskew_mod
import planodom.odometry.odometry as odo_mod
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.extraction import extract_planes
from planodom.geometry import invert_transform, se3_log
from planodom.odometry import run_odometry
from planodom.odometry.relative import Status
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.simulation.simulate import simulate

ROWS: dict[int, dict[str, Any]] = {}


def instrument(steps: range, probes: dict[int, dict[str, np.ndarray]]) -> None:
    """Record every extraction of the epochs in ``steps`` and probe them with ``probes``."""
    real_register = deskew_mod.register_deskewed
    real_estimate_scan = odo_mod.PlaneOdometry._estimate_scan
    state: dict[str, Any] = {}

    def estimate_scan(self: Any, scan: Any, *a: Any, **k: Any) -> Any:
        state["k"], state["odo"] = len(self.poses), self
        state["tm"] = float(np.mean(scan.t)) if scan.t is not None else 0.0
        return real_estimate_scan(self, scan, *a, **k)

    def register(predicted: Any, dt: float, estimate: Any, *a: Any, **k: Any) -> Any:
        passes: list[tuple[str, Any, Any]] = []
        held = a[3] if len(a) > 3 else None  # (refresh, config, previous, held, ...)

        def labelled(twist: Any, source: Any = None) -> Any:
            got = estimate(twist) if source is None else estimate(twist, source)
            kind = "own" if source is not None else _kind(twist, predicted, held)
            passes.append((kind, twist, got))
            return got

        best = real_register(predicted, dt, labelled, *a, **k)
        epoch = state["k"]
        if epoch in steps:
            row: dict[str, Any] = {"dt": dt, "passes": passes, "best": best, "probes": {}}
            odo = state["odo"]
            for name, twist in probes.get(epoch, {}).items():
                row["probes"][name] = estimate(twist)
            first = [g for kind, _, g in passes if kind != "own"]
            kept = max(first, key=lambda g: (g.relative.status.rank, len(g.planes)))
            previous = odo._rates[-1][1] if odo._rates and odo._rates[-1][0] == epoch - 1 else None
            if kept.relative.status is not Status.UNRESOLVED and previous is not None:
                own = kept.own_twist(dt)
                row["led"] = led_to_centre(own, previous, dt, state["tm"])
                row["probes"]["own led"] = estimate(row["led"])
            ROWS[epoch] = row
        return best

    odo_mod.register_deskewed = register
    odo_mod.PlaneOdometry._estimate_scan = estimate_scan  # type: ignore[method-assign]


def _kind(twist: Any, predicted: Any, held: Any) -> str:
    if twist is None:
        return "none"
    if predicted is not None and np.array_equal(twist, predicted):
        return "pred"
    if held is not None and np.array_equal(twist, held):
        return "held"
    return "trend"


def centre_twist(sim: Any, k: int) -> np.ndarray:
    """(6,) the true mean body twist over epoch ``k``'s points' time span (rad/s, m/s)."""
    t = np.asarray(sim.scans[k].t)
    a, b = sim.times[k] + float(t.min()), sim.times[k] + float(t.max())
    Ta, Tb = sim.trajectory.pose(a), sim.trajectory.pose(b)
    return se3_log(invert_transform(Ta) @ Tb) / (b - a)


def step_twist(sim: Any, k: int) -> np.ndarray:
    """(6,) the true twist of the step ``k - 1 -> k`` (rad/s, m/s)."""
    T = invert_transform(sim.poses[k - 1]) @ sim.poses[k]
    return se3_log(T) / float(sim.times[k] - sim.times[k - 1])


def led_to_centre(own: np.ndarray, previous: np.ndarray | None, dt: float, tm: float) -> np.ndarray:
    """(6,) ``own`` (the mean over a step of ``dt`` s) led to the points' mean time ``tm``
    s after the epoch, along its change since ``previous`` (the step before's)."""
    if previous is None:
        return own
    out = own.copy()
    out[:3] += (dt / 2 + tm) / dt * (own[:3] - previous[:3])
    return out


def err(twist: Any, truth: np.ndarray) -> str:
    """Yaw-rate error and roll/pitch-rate error norm (deg/s) of ``twist`` against ``truth``."""
    if twist is None:
        return "   -  /   - "
    d = np.degrees(np.asarray(twist)[:3] - truth[:3])
    return f"{d[2]:+5.2f}/{np.hypot(d[0], d[1]):4.2f}"


def surfaces(est: Any, ground: int) -> str:
    """``planes/distinct true surfaces`` of an estimate, ``g`` when the ground is one."""
    ids = [p.truth_id for p in est.planes]
    g = "g" if ground in ids else " "
    return f"{len(ids):2d}/{len(set(ids)):2d}{g}"


def why(row: dict[str, Any]) -> str:
    """Why the refinement with the epoch's own twist did not recover (module docstring)."""
    passes, best = row["passes"], row["best"]
    first = [p for p in passes if p[0] != "own"]
    own = [p for p in passes if p[0] == "own"]
    kept_first = next((g for kind, _, g in first if g is best), None)
    if kept_first is not None and kept_first.relative.status is Status.UNRESOLVED:
        return "unresolved"
    if not own and kept_first is not None and kept_first.twist is None:
        if kept_first.relative.status is not Status.OK:
            return "not deskewed, velocity unmeasured"
    if not own:
        return "tolerance"
    if any(g is best for _, _, g in own):
        return "kept"
    return "worse"


def report(sim: Any, ground: int) -> None:
    for k in sorted(ROWS):
        row, truth, step = ROWS[k], centre_twist(sim, k), step_twist(sim, k)
        print(f"epoch {k}: truth centre rate {np.round(np.degrees(truth[:3]), 2)} deg/s, "
              f"step {np.round(np.degrees(step[:3]), 2)}")  # fmt: skip
        for kind, twist, got in row["passes"]:
            mark = "*" if got is row["best"] else " "
            print(f"   {mark}{kind:5s} {err(twist, truth)}  {got.relative.status.name[:5]:5s} "
                  f"{surfaces(got, ground)}")  # fmt: skip
        first = next(g for kind, _, g in row["passes"] if kind != "own")
        kept_first = max((g for kind, _, g in row["passes"] if kind != "own"),
                         key=lambda g: (g.relative.status.rank, len(g.planes)))  # fmt: skip
        own = kept_first.own_twist(row["dt"]) if first is not None else None
        resolved = kept_first.relative.status is not Status.UNRESOLVED
        print(f"    own vs centre {err(own if resolved else None, truth)}, vs step "
              f"{err(own if resolved else None, step)}; why: {why(row)}")  # fmt: skip
        if "led" in row:
            print(f"    own led to the points' mean time {err(row['led'], truth)}")
        for name, got in row["probes"].items():
            print(f"    probe {name:11s} {got.relative.status.name[:5]:5s} {surfaces(got, ground)}")


def exact(world_index: int, noises: list[float], steps: range) -> None:
    """The ``--exact`` table (module docstring)."""
    world = world_for(world_index)
    dt, config = 1.0 / world.epoch_rate, PlanodomConfig()

    def step(k: int) -> np.ndarray:
        T = invert_transform(world.trajectory.pose((k - 1) * dt)) @ world.trajectory.pose(k * dt)
        return se3_log(T) / dt

    for noise in noises:
        for k in steps:
            sim = simulate(world.scene, world.trajectory, world.sensor_rig, n_epochs=1,
                           epoch_rate=world.epoch_rate, noise_sigma=noise, seed=1,
                           start_time=k * dt)  # fmt: skip
            scan = sim.scans[0]
            t = np.asarray(scan.t)
            a, b = k * dt + float(t.min()), k * dt + float(t.max())
            truth = se3_log(invert_transform(world.trajectory.pose(a)) @ world.trajectory.pose(b))
            truth = truth / (b - a)
            own, led = step(k), step(k).copy()
            led[2] += (own[2] - step(k - 1)[2]) * (0.5 + float(np.mean(t)) / dt)
            cells = []
            for name, tw in (("step before", step(k - 1)), ("own step", own), ("led", led),
                             ("points", truth)):  # fmt: skip
                planes = extract_planes(scan, config.extraction, twist=tw,
                                        sensor_origins=sim.rig.sensor_origins)  # fmt: skip
                ids = [p.truth_id for p in planes]
                g = "g" if 0 in ids else " "
                yaw = np.degrees(tw[2] - truth[2])
                cells.append(f"{name} {yaw:+.2f} {len(ids)}/{len(set(ids))}{g}")
            print(f"{noise * 1000:g} mm, epoch {k}: " + " | ".join(cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--world", type=int, default=None)
    ap.add_argument("--scene", default=None)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006])
    ap.add_argument("--exact", action="store_true", help="true twists only, nothing run")
    ap.add_argument("--steps", type=int, nargs=2, default=[70, 82])
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    steps = range(args.steps[0], args.steps[1] + 1)
    if args.exact:
        return exact(args.world, args.noise, steps)
    config = config_with(args.set)
    args.noise = args.noise[0]
    if args.world is not None:
        world = world_for(args.world)
        sim = simulate_world(world, args.noise, n_epochs=steps.stop + 1, all_fields=True)
        source, config, rig = world_fields(world, sim), declared_sweep(world, config), None
    else:
        sim, _ = simulated(args.scene, str(args.noise))
        source, rig = sim, sim.rig
    probes = {k: {"true centre": centre_twist(sim, k), "true step": step_twist(sim, k)}
              for k in steps}  # fmt: skip
    instrument(steps, probes)
    try:
        run_odometry(source, config, rig, progress=partial(_stop_after, steps.stop))
    except _Done:
        pass
    report(sim, ground=0)


class _Done(Exception):
    """Raised after the last epoch traced: the rest of the lap is not run."""


def _stop_after(last: int, k: int, n: int) -> None:
    if k >= last:
        raise _Done


if __name__ == "__main__":
    main()
