"""Which epochs of a built-in scene gain a narrow plane, and what it does to their steps
(issue 11, NARROW4).

Per built-in scene and noise (``planodom run --scenario`` defaults, as
``builtin_scenes.py``) the odometry runs twice: ``--set`` overrides (the base) and the
base plus ``--variant`` overrides (default ``extraction.narrow_seed_last_deg=0.5``). An
epoch's *gained* planes are the variant's planes that match none of the base's planes of
the same epoch (same true surface, normals within 0.5 deg, offsets within 5 cm): with
``narrow_seed_last_deg`` the wide seeds' planes are kept as they are, so these are the
narrow seeds' planes (or planes of a different deskew). For each gained plane: its error
against its true surface (normal, mrad; offset, cm), its fit covariance's stated sigmas
(normal, mrad; offset, cm), the normalised errors (error / stated sigma), points and
rings, and whether the step into its epoch or out of it associates it.

Then the steps are split into those that associate a gained plane and the others, and
per class the sum of squared xy and rotation step errors (base -> variant): where the
ATE's growth comes from. ``--steps`` prints those steps' rows.

    uv run python experiments/narrow_trace.py --scene paper-loop --noise 0.02
    uv run python experiments/narrow_trace.py --scene paper-loop --noise 0 --steps
    uv run python experiments/narrow_trace.py --world 284 --noise 0.02 --steps
"""

from __future__ import annotations

import argparse

import numpy as np
from builtin_scenes import config_with, simulated

from planodom.geometry import invert_transform, transform_planes
from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry import run_odometry


def step_errors(poses: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(E-1,) rotation (deg) and xy (cm) errors of the steps."""
    err = per_epoch_errors(relative_motions(poses), relative_motions(gt))
    rot = np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))
    return rot, np.hypot(err["x"], err["y"]) * 100


def truth_of(plane, T_world_base: np.ndarray, scene):  # noqa: ANN001, ANN201
    """(normal (3,), offset) of ``plane``'s true surface in the base frame, or None."""
    ids = {int(i): j for j, i in enumerate(scene.ids)}
    j = ids.get(int(plane.truth_id))
    if j is None:
        return None
    n_w, d_w = transform_planes(invert_transform(T_world_base), scene.normals[j : j + 1],
                                scene.offsets[j : j + 1])  # fmt: skip
    n, d = n_w[0], float(d_w[0])
    return (n, d) if plane.normal @ n >= 0 else (-n, -d)


def matched(p, planes) -> bool:  # noqa: ANN001
    return any(
        q.truth_id == p.truth_id
        and q.normal @ p.normal > np.cos(np.radians(0.5))
        and abs(q.offset - p.offset) < 0.05
        for q in planes
    )


def gained_rows(sim, base, var) -> list[dict]:  # noqa: ANN001
    """The gained planes of every epoch (module docstring)."""
    out = []
    for k in range(len(var.planes)):
        for m, p in enumerate(var.planes[k]):
            if matched(p, base.planes[k]):
                continue
            true = truth_of(p, sim.poses[k], sim.scene)
            ang = off = np.nan
            if true is not None:
                ang = float(np.arccos(np.clip(p.normal @ true[0], -1, 1))) * 1e3
                off = abs(p.offset - true[1]) * 100
            C = p.covariance
            s_n = float(np.sqrt(np.trace(C[:3, :3]))) * 1e3
            s_d = float(np.sqrt(C[3, 3])) * 100
            used = []
            r_in = var.results[k]
            if r_in is not None and m in set(r_in.associations[:, 1].tolist()):
                used.append("in")
            r_out = var.results[k + 1] if k + 1 < len(var.results) else None
            if (
                r_out is not None
                and r_out.prev == k
                and m in set(r_out.associations[:, 0].tolist())
            ):
                used.append("out")
            out.append({
                "epoch": k, "plane": m, "truth": int(p.truth_id), "normal": p.normal,
                "ang_mrad": ang, "off_cm": off, "s_n_mrad": s_n, "s_d_cm": s_d,
                "points": p.support.n_points if p.support is not None else -1,
                "rows": p.support.n_rows if p.support is not None else -1,
                "used": used,
            })  # fmt: skip
    return out


def simulated_seed(scene: str, noise: str, seed: int):  # noqa: ANN201
    """:func:`builtin_scenes.simulated` with the simulation's seed ``seed``."""
    if seed == 0:
        return simulated(scene, noise)
    from planodom.cli.common import simulate_scene

    sim = simulate_scene(scene, "isoclinal", noise, seed, None, "continuous")
    return sim, invert_transform(sim.poses[0])[None] @ sim.poses


def generalisation_world(index: int, noise: float, epochs: int = 150):  # noqa: ANN201
    """World ``index`` of ``planodom experiment generalisation`` (its first ``epochs``),
    its truth, and a function running planodom's odometry on it as the experiment does."""
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.simulation.random_world import simulate_world, world_fields

    world = world_for(index)
    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    run = world_fields(world, full)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    return full, gt, lambda c: run_odometry(run, declared_sweep(world, c))


def chained(steps: np.ndarray) -> np.ndarray:
    """(E, 4, 4) poses from the first (identity) chained through ``steps`` (E-1, 4, 4)."""
    out = [np.eye(4)]
    for s in steps:
        out.append(out[-1] @ s)
    return np.array(out)


def mixed(a: np.ndarray, b: np.ndarray, mask: np.ndarray, part: str) -> np.ndarray:
    """Steps of ``a`` with those under ``mask`` taken from ``b``: whole, or only their
    rotation (``rot``: b's rotation, a's translation) or translation (``trans``)."""
    out = a.copy()
    if part == "all":
        out[mask] = b[mask]
    elif part == "rot":
        out[mask, :3, :3] = b[mask, :3, :3]
    else:
        out[mask, :3, 3] = b[mask, :3, 3]
    return out


def print_hybrids(base: np.ndarray, var: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> None:
    """ATE xy of the base's steps with the variant's in the steps ``mask`` (whole, rotation
    or translation only), and with the variant's everywhere else: which steps carry the
    ATE's change."""
    sa, sb = relative_motions(base), relative_motions(var)
    err = lambda P: ate(P, gt, "origin", xy_only=True)["rmse"]  # noqa: E731
    print(f"ATE xy, chained steps: base {err(chained(sa)):.4f}, variant {err(chained(sb)):.4f}")
    for part in ("all", "rot", "trans"):
        print(f"  base + variant's {part} at the gained steps: "
              f"{err(chained(mixed(sa, sb, mask, part))):.4f}; variant + base's {part} there: "
              f"{err(chained(mixed(sb, sa, mask, part))):.4f}")  # fmt: skip
    ya = per_epoch_errors(sa, relative_motions(gt))["yaw"]
    yb = per_epoch_errors(sb, relative_motions(gt))["yaw"]
    print(f"  summed signed yaw error (deg): gained steps {np.degrees(ya[mask].sum()):+.4f} -> "
          f"{np.degrees(yb[mask].sum()):+.4f}; others {np.degrees(ya[~mask].sum()):+.4f} -> "
          f"{np.degrees(yb[~mask].sum()):+.4f}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="paper-loop")
    parser.add_argument("--noise", default="0.02")
    parser.add_argument(
        "--set", nargs="*", action="extend", default=[], help="base overrides key=value"
    )
    parser.add_argument("--variant", nargs="*", default=["extraction.narrow_seed_last_deg=0.5"])
    parser.add_argument("--steps", action="store_true", help="rows of the steps involved")
    parser.add_argument("--seed", type=int, default=0, help="the simulation's noise seed")
    parser.add_argument("--world", type=int, default=-1,
                        help="a generalisation world instead of --scene (150 epochs)")  # fmt: skip
    parser.add_argument("--save", default="", help="npz of both runs' poses and the truth")
    args = parser.parse_args()
    if args.world >= 0:
        sim, gt, run_of = generalisation_world(args.world, float(args.noise))
    else:
        sim, gt = simulated_seed(args.scene, args.noise, args.seed)
        run_of = lambda c: run_odometry(sim, c, sim.rig)  # noqa: E731
    base = run_of(config_with(args.set))
    var = run_of(config_with(args.set + args.variant))
    for name, run in (("base", base), ("variant", var)):
        print(f"{name}: ATE xy {ate(run.poses, gt, 'origin', xy_only=True)['rmse']:.4f} m, "
              f"3-D {ate(run.poses, gt, 'origin')['rmse']:.4f} m, unresolved "
              f"{run.n_unresolved}, degenerate {run.n_degenerate}")  # fmt: skip
    rot_a, xy_a = step_errors(base.poses, gt)
    rot_b, xy_b = step_errors(var.poses, gt)
    rows = gained_rows(sim, base, var)
    print(
        f"gained planes: {len(rows)} in {len({r['epoch'] for r in rows})} epochs; "
        f"associated {sum(bool(r['used']) for r in rows)}"
    )
    if rows:
        used = [r for r in rows if r["used"]] or rows
        for key in ("ang_mrad", "off_cm", "s_n_mrad", "s_d_cm"):
            v = np.array([r[key] for r in used])
            print(f"  {key}: median {np.nanmedian(v):.3f}, max {np.nanmax(v):.3f}")
        z_n = np.array([r["ang_mrad"] / r["s_n_mrad"] for r in used])
        z_d = np.array([r["off_cm"] / r["s_d_cm"] for r in used])
        print(f"  normal error / stated sigma: median {np.nanmedian(z_n):.2f}, "
              f"max {np.nanmax(z_n):.2f}; offset: median {np.nanmedian(z_d):.2f}, "
              f"max {np.nanmax(z_d):.2f}")  # fmt: skip
        hz = np.array([np.degrees(np.arcsin(min(1.0, abs(r["normal"][2])))) for r in used])
        print(f"  elevation of the normals (deg): {np.round(np.sort(hz), 1).tolist()[:40]}")
        print(f"  true surfaces: {sorted({r['truth'] for r in used})}")
    steps = set()
    for r in rows:
        if "in" in r["used"]:
            steps.add(r["epoch"] - 1)  # the step into epoch k is step index k - 1
        if "out" in r["used"]:
            steps.add(r["epoch"])
    involved = np.zeros(len(xy_a), dtype=bool)
    involved[[s for s in steps if 0 <= s < len(xy_a)]] = True
    for label, mask in (("with a gained plane", involved), ("others", ~involved)):
        print(f"steps {label}: {int(mask.sum())}; sum xy^2 {np.sum(xy_a[mask] ** 2):.3f} -> "
              f"{np.sum(xy_b[mask] ** 2):.3f} cm^2; sum rot^2 {np.sum(rot_a[mask] ** 2):.5f} "
              f"-> {np.sum(rot_b[mask] ** 2):.5f} deg^2; mean xy {np.mean(xy_a[mask]):.3f} "
              f"-> {np.mean(xy_b[mask]):.3f} cm")  # fmt: skip
    print_hybrids(base.poses, var.poses, gt, involved)
    worst = np.argsort(-np.abs(xy_b - xy_a))[:8]
    print("steps changed most (xy cm, rotation deg, statuses, planes of both epochs):")
    for s in sorted(worst.tolist()):
        print(f"  {s}->{s + 1}: xy {xy_a[s]:.3f} -> {xy_b[s]:.3f}, rot {rot_a[s]:.4f} -> "
              f"{rot_b[s]:.4f}, {base.statuses[s + 1]} -> {var.statuses[s + 1]}, planes "
              f"{len(base.planes[s])}/{len(base.planes[s + 1])} -> "
              f"{len(var.planes[s])}/{len(var.planes[s + 1])}"
              f"{' (gained)' if involved[s] else ''}")  # fmt: skip
    if args.save:
        np.savez(args.save, base=base.poses, variant=var.poses, gt=gt, involved=involved)
    if args.steps:
        by_epoch: dict[int, list[dict]] = {}
        for r in rows:
            by_epoch.setdefault(r["epoch"], []).append(r)
        for s in sorted(steps):
            gained = by_epoch.get(s, []) + by_epoch.get(s + 1, [])
            desc = "; ".join(
                f"e{r['epoch']} p{r['plane']} s{r['truth']} {'/'.join(r['used'])} "
                f"{r['ang_mrad']:.2f}mrad {r['off_cm']:.2f}cm (stated {r['s_n_mrad']:.2f}, "
                f"{r['s_d_cm']:.2f}) {r['points']}pts"
                for r in gained if r["used"]
            )  # fmt: skip
            print(f"  step {s}->{s + 1}: xy {xy_a[s]:.3f} -> {xy_b[s]:.3f} cm, rot "
                  f"{rot_a[s]:.4f} -> {rot_b[s]:.4f} deg | {desc}")  # fmt: skip


if __name__ == "__main__":
    main()
