"""SPEED2D9's exact cuts of the solver's glue against the code they replaced, in one process.

The 2D rig's default odometry runs each world's simulated run with the code as it is
("cuts") and with the former expressions put back ("former": the ``numpy_*`` functions
of :mod:`planodom.odometry.solver_glue`, ``np.append``, ``np.isfinite(...).all()`` and
boolean indexing): the translation consensus's pair ids, the winner's neighbours, the
refinement's initial translation, the rotation covariance's finiteness test, the rows
kept by boolean masks (translation elements, agreeing pairs, the winner's neighbours),
the remapping of the solve's associations to the input order, and the refinement's
planes gathered in its compiled call (former: by numpy). They alternate,
``--reps`` times each after an untimed warm-up of both, with KISS-ICP on the same scans
(as ``bench_rig2d_vs_kiss.py`` runs it); the fastest repetition of each counts (process
time). Per world: both variants' CPU ms an epoch, their ratio, KISS-ICP's, and
planodom's epochs/s as a multiple of KISS-ICP's with each; the two variants' poses must
be the same bits (checked on every repetition). (``rotation_covariance``'s
``math.isnan`` of one value, for ``np.isnan``, is in both.)

    uv run --extra baselines python experiments/bench_glue_cuts9.py --noise 0.02 \\
        --epochs 150 --worlds 160 162 164 168 170 172 --reps 5
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import planodom.odometry.refine as refine  # noqa: E402
import planodom.odometry.solver as solver  # noqa: E402
import planodom.odometry.translation as translation  # noqa: E402
import planodom.se3 as se3  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.experiments.peers import kiss_available, kiss_icp_poses  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.odometry.solver_glue import (  # noqa: E402
    numpy_near_rows,
    numpy_pair_ids,
    numpy_remapped_pairs,
)
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402


def former_all_finite(a: np.ndarray, b: np.ndarray) -> bool:
    """The rotation covariance's finiteness test before SPEED2D9."""
    return bool(np.isfinite(a).all() and np.isfinite(b).all())


def former_appended(txy: np.ndarray, z: float) -> np.ndarray:
    """The refinement's initial translation before SPEED2D9."""
    return np.append(txy, z)


def former_gathered_fit(
    prev: Any, curr: Any, i: np.ndarray, j: np.ndarray, R: np.ndarray, t0: np.ndarray,
    rest: tuple[Any, ...],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:  # fmt: skip
    """``plane_translation``'s fit before SPEED2D9: the planes' rows gathered by numpy."""
    return refine._translation_kernel(
        prev.normals[i], prev.offsets[i], prev.covariances[i], curr.normals[j],
        curr.offsets[j], curr.covariances[j], R, t0, *rest,
    )  # fmt: skip


def former_kept_rows(mask: np.ndarray, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """The boolean selections of rows before SPEED2D9."""
    return tuple(a[mask] for a in arrays)


#: (object, attribute, former): what "former" puts back
FORMER = (
    (solver, "pair_ids", numpy_pair_ids),
    (solver, "near_rows", numpy_near_rows),
    (solver, "appended", former_appended),
    (solver, "all_finite", former_all_finite),
    (solver, "remapped_pairs", numpy_remapped_pairs),
    (solver, "kept_rows", former_kept_rows),
    (refine, "gathered_fit", former_gathered_fit),
    (translation, "kept_rows", former_kept_rows),
)
CUTS = tuple((obj, name, getattr(obj, name)) for obj, name, _ in FORMER)


def use(variant: str) -> None:
    """Put the ``variant``'s functions in place ("cuts" or "former")."""
    for obj, name, fn in CUTS if variant == "cuts" else FORMER:
        setattr(obj, name, fn)
    se3._twist_step.cache_clear()  # no prediction remembered from the other variant's run


def one_world(w: int, noise: float, epochs: int, reps: int) -> dict:
    """CPU ms an epoch (best of ``reps``) of both variants and KISS-ICP on world ``w``."""
    world = world_for(w)
    cfg = declared_sweep(world, PlanodomConfig())
    run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
    warm = world_fields(world, simulate_world(world, 0.0, n_epochs=3, all_fields=True))
    max_range = max(s.max_range for s in world.sensor_rig.sensors)
    period = 1.0 / world.epoch_rate
    for name in ("former", "cuts"):
        use(name)
        run_odometry(warm, cfg)
    kiss_icp_poses(warm.scans, period, max_range)
    cpu: dict[str, list[float]] = {"former": [], "cuts": [], "kiss": []}
    poses: dict[str, np.ndarray] = {}
    for _ in range(reps):
        for name in ("former", "cuts"):
            use(name)
            c0 = time.process_time()
            odo = run_odometry(run, cfg)
            cpu[name].append(time.process_time() - c0)
            poses[name] = np.asarray(odo.poses, dtype=np.float64)
        if not np.array_equal(poses["cuts"], poses["former"]):
            raise SystemExit(f"world {w}: the two variants' poses differ")
        c0 = time.process_time()
        kiss_icp_poses(run.scans, period, max_range)
        cpu["kiss"].append(time.process_time() - c0)
    use("cuts")
    ms = {name: 1e3 * min(v) / epochs for name, v in cpu.items()}
    return {"world": w, "kind": world.kind, **ms}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[160, 162, 164, 168, 170, 172])
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--reps", type=int, default=5)
    args = ap.parse_args()
    if not kiss_available():
        raise SystemExit("KISS-ICP is not installed: uv sync --extra baselines")
    if any(w % 2 for w in args.worlds):
        raise SystemExit("the 2D rig's worlds are the even ones")
    print(f"{args.noise * 1e3:g} mm, {args.epochs} epochs, CPU ms an epoch (best of {args.reps})")
    shares, before, after = [], [], []
    for w in args.worlds:
        r = one_world(w, args.noise, args.epochs, args.reps)
        shares.append(r["cuts"] / r["former"])
        before.append(r["kiss"] / r["former"])
        after.append(r["kiss"] / r["cuts"])
        print(
            f"world {w:3d} {r['kind']:7s} | former {r['former']:6.2f} cuts {r['cuts']:6.2f} "
            f"ratio {shares[-1]:.3f} | KISS-ICP {r['kiss']:6.2f} | x KISS-ICP: "
            f"{before[-1]:.3f} -> {after[-1]:.3f}",
            flush=True,
        )
    print(
        f"median cuts / former {np.median(shares):.3f}; x KISS-ICP {np.median(before):.3f} "
        f"-> {np.median(after):.3f} ({len(shares)} worlds)"
    )


if __name__ == "__main__":
    main()
