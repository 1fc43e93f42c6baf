"""Refinements of a worse status, against the truth (issue 11, RANKREF).

The deskewing policy (:mod:`planodom.odometry.deskew`, step 2) drops a refinement with the
epoch's own twist when its status is worse than the estimate it was refined from (unless
the reference was extracted again for it). Each 2D-rig world of ``--first-world`` and
``--worlds`` (even indices, as ``planodom experiment generalisation --rig rig2d`` runs them)
is run at ``--noise`` with the default config (or ``--set`` overrides), every such
refinement recorded: the statuses, the planes and distinct surfaces
(:func:`planodom.odometry.surfaces.distinct_surfaces`, the association's margins) of the
estimate refined from, of the refinement and of its reference, whether the reference was
the same (False: extracted again for it, so the refinement was kept), and each step's
rotation (deg) and xy (cm) error against the true step. Per world a line, then the
totals: how many hold the three conditions of ``odometry.split_reference: split``, and
for those dropped against the same reference that turned an OK step degenerate, how
often the dropped refinement's rotation was the closer to the truth, with both medians.

    uv run python experiments/dropped_refinements.py --first-world 140 --worlds 20 --noise 0.006
"""

from __future__ import annotations

import argparse
import statistics
from typing import Any

import numpy as np
from builtin_scenes import config_with

import planodom.odometry.odometry as odo_mod
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.geometry import invert_transform, se3_log
from planodom.odometry import run_odometry
from planodom.odometry.relative import Status
from planodom.odometry.surfaces import distinct_surfaces
from planodom.simulation.random_world import simulate_world, world_fields

ROWS: list[dict[str, Any]] = []


def instrument(state: dict[str, Any]) -> None:
    """Record every refinement of a worse status (module docstring) in ``ROWS``."""
    real = odo_mod.split_reference

    def wrap(odometry: Any, estimate: Any) -> Any:
        inner = real(odometry, estimate)
        tol = odometry.config.association.normal_tol_deg, odometry.config.association.offset_tol_m

        def recorded(twist: Any, source: Any = None) -> Any:
            out = inner(twist) if source is None else inner(twist, source)
            if source is not None and out.relative.status.rank < source.relative.status.rank:
                k, poses = len(odometry.poses), state["sim"].poses
                truth = invert_transform(poses[k - 1]) @ poses[k]
                row = {"world": state["world"], "epoch": k, "from": source.relative.status,
                       "to": out.relative.status,
                       "same_ref": out.reference_planes is source.reference_planes}  # fmt: skip
                for name, planes in (("source", source.planes), ("again", out.planes),
                                     ("ref", out.reference_planes)):  # fmt: skip
                    row[name] = (len(planes), distinct_surfaces(planes, *tol))
                for name, e in (("source", source), ("again", out)):
                    d = se3_log(invert_transform(truth) @ e.step)
                    row[f"{name}_err"] = (float(np.degrees(np.linalg.norm(d[:3]))),
                                          float(np.linalg.norm(d[3:5]) * 100))  # fmt: skip
                ROWS.append(row)
            return out

        return recorded

    odo_mod.split_reference = wrap


def conditions(row: dict[str, Any]) -> bool:
    """``split``'s (b) and (c): fewer fragments than the estimate refined from, against a
    reference with split walls ((a), a worse status, holds for every row)."""
    fragments = {name: row[name][0] - row[name][1] for name in ("source", "again", "ref")}
    return fragments["again"] < fragments["source"] and fragments["ref"] > 0


def summary(rows: list[dict[str, Any]]) -> str:
    """The totals (module docstring)."""
    dropped = [r for r in rows if r["same_ref"]]
    ok_degen = [r for r in dropped if r["from"] is Status.OK and r["to"] is Status.DEGENERATE]
    text = (f"{len(rows)} refinements of a worse status, {sum(map(conditions, rows))} with "
            f"split's conditions; {len(dropped)} dropped (same reference), {len(ok_degen)} "
            "of them OK -> degenerate")  # fmt: skip
    if ok_degen:
        kept = [r["source_err"][0] for r in ok_degen]
        again = [r["again_err"][0] for r in ok_degen]
        closer = sum(a < k for k, a in zip(kept, again, strict=True))
        text += (f": the dropped rotation closer to the truth in {closer}, median "
                 f"{statistics.median(again):.3f} deg against the kept "
                 f"{statistics.median(kept):.3f}, mean {statistics.mean(again):.3f} against "
                 f"{statistics.mean(kept):.3f}")  # fmt: skip
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--first-world", type=int, default=140)
    ap.add_argument("--worlds", type=int, default=20)
    ap.add_argument("--noise", type=float, default=0.006)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    state: dict[str, Any] = {}
    instrument(state)
    first = args.first_world + args.first_world % 2  # the 2D rig's worlds are even
    for index in range(first, args.first_world + args.worlds, 2):
        world = world_for(index)
        sim = simulate_world(world, args.noise, n_epochs=args.epochs, all_fields=True)
        state.update(sim=sim, world=index)
        config = declared_sweep(world, config_with(args.set))
        run_odometry(world_fields(world, sim), config)
        print(f"world {index}: " + summary([r for r in ROWS if r["world"] == index]), flush=True)
    print(f"all, {args.noise * 1000:g} mm: " + summary(ROWS))


if __name__ == "__main__":
    main()
