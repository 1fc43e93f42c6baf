"""SPEED2D8's exact cuts of the solver's and odometry's glue against the code they replaced,
in one process.

The 2D rig's default odometry runs each world's simulated run with the code as it is
("cuts") and with the four former expressions put back ("former", below):
``orthonormalised``'s check in numpy, ``rotation_covariance``'s concatenation and block
diagonal in numpy, ``se3_exp`` with both branches through ``np.where``, and
``plane_associations`` with copied indices, the odometry's inverse of an identity chain
computed at every estimate, the solver's pairs agreeing with the rotation and its height
elements in numpy. They alternate, ``--reps`` times each after an
untimed warm-up of both, with KISS-ICP on the same scans (as ``bench_rig2d_vs_kiss.py``
runs it). The fastest repetition of each counts (process time: the machine's load moves
wall time by more than the difference). Per world: both variants' CPU ms an epoch, their
ratio, KISS-ICP's, and planodom's epochs/s as a multiple of KISS-ICP's with each; the
poses of the two variants must be the same bits (checked on every repetition).

    uv run --extra baselines python experiments/bench_glue_cuts.py --noise 0.02 \\
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

import planodom.extraction.epoch as extraction_epoch  # noqa: E402
import planodom.geometry as geometry  # noqa: E402
import planodom.odometry.odometry as odometry_module  # noqa: E402
import planodom.odometry.propagate as propagate  # noqa: E402
import planodom.odometry.solver as solver  # noqa: E402
import planodom.se3 as se3  # noqa: E402
from planodom.association import PairAssociations, _unique_pairs  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.experiments.peers import kiss_available, kiss_icp_poses  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.odometry.pair_agreement import numpy_agreeing  # noqa: E402
from planodom.odometry.translation import HeightElements  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402


def former_is_orthonormal(R: np.ndarray, tol: float) -> bool:
    """``orthonormalised``'s check before SPEED2D8."""
    return bool(np.max(np.abs(R.T @ R - np.eye(3))) <= tol)


def former_stacked(
    prev_normals: np.ndarray, curr_normals: np.ndarray, prev_cov: np.ndarray, curr_cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``rotation_covariance``'s vector and block diagonal before SPEED2D8."""
    x = np.concatenate([prev_normals.ravel(), curr_normals.ravel()])
    S = propagate._block_diag([c[:3, :3] for c in (*prev_cov, *curr_cov)])
    return x, S


def former_se3_exp(xi: np.ndarray) -> np.ndarray:
    """``se3_exp`` before SPEED2D8 (both branches through ``np.where``)."""
    xi = np.asarray(xi, dtype=np.float64)
    flat = xi.reshape(-1, 6)
    w, v = flat[:, :3], flat[:, 3:]
    th = np.linalg.norm(w, axis=1)
    small = th < 1e-3
    ths = np.where(small, 1.0, th)
    t2 = th**2
    a = np.where(small, 1.0 - t2 / 6.0 + t2**2 / 120.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - t2 / 24.0 + t2**2 / 720.0, (1.0 - np.cos(ths)) / ths**2)
    c = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t2**2 / 5040.0, (ths - np.sin(ths)) / ths**3)
    K = se3._skew(w)
    K2 = K @ K
    eye = np.eye(3)
    out = np.zeros((len(flat), 4, 4))
    out[:, :3, :3] = eye + a[:, None, None] * K + b[:, None, None] * K2
    V = eye + b[:, None, None] * K + c[:, None, None] * K2
    out[:, :3, 3] = np.einsum("tij,tj->ti", V, v)
    out[:, 3, 3] = 1.0
    return out.reshape(xi.shape[:-1] + (4, 4))


def former_inverse_chain(T_ref_last: np.ndarray, steps: list[np.ndarray]) -> np.ndarray:
    """The odometry's ``invert_transform(T_ref_last)`` of every estimate before SPEED2D8."""
    return geometry.invert_transform(T_ref_last)


def former_height_elements(prev: Any, curr: Any, ij: np.ndarray, max_tilt: float) -> Any:
    """``height_elements`` before SPEED2D8 (numpy)."""
    n = prev.normals[ij[:, 0]]
    keep = n[:, 2] >= np.cos(max_tilt)
    ij, n = ij[keep], n[keep]
    b = (curr.offsets[ij[:, 1]] - prev.offsets[ij[:, 0]]) / n[:, 2]
    w = prev.weights[ij[:, 0]] * curr.weights[ij[:, 1]]
    return HeightElements(b, n[:, :2] / n[:, 2:3], w, ij)


def former_plane_associations(self: PairAssociations, index: Any = None) -> np.ndarray:
    """``PairAssociations.plane_associations`` before SPEED2D8 (copied indices)."""
    pp, cp = self.prev_pairs, self.curr_pairs
    if index is not None:
        pp, cp = pp[index], cp[index]
    return _unique_pairs(pp.astype(np.int64), cp.astype(np.int64)).astype(np.intp)


#: (object, attribute, former): what "former" puts back
FORMER = (
    (geometry, "is_orthonormal", former_is_orthonormal),
    (propagate, "_stacked", former_stacked),
    (se3, "se3_exp", former_se3_exp),
    (extraction_epoch, "se3_exp", former_se3_exp),
    (PairAssociations, "plane_associations", former_plane_associations),
    (odometry_module, "inverse_chain", former_inverse_chain),
    (solver, "agreeing_pairs", numpy_agreeing),
    (solver, "height_elements", former_height_elements),
)


def cuts_of(former: tuple) -> tuple:
    """(object, attribute, function as it is now) for each entry of ``former``."""
    return tuple((obj, name, getattr(obj, name)) for obj, name, _ in former)


CUTS = cuts_of(FORMER)


def use(variant: str, cuts: tuple = CUTS, former: tuple = FORMER) -> None:
    """Put the ``variant``'s functions in place ("cuts" or "former")."""
    for obj, name, fn in cuts if variant == "cuts" else former:
        setattr(obj, name, fn)
    se3._twist_step.cache_clear()  # no prediction remembered from the other variant's run


def one_world(
    w: int, noise: float, epochs: int, reps: int, cuts: tuple = CUTS, former: tuple = FORMER
) -> dict:
    """CPU ms an epoch (best of ``reps``) of both variants and KISS-ICP on world ``w``."""
    world = world_for(w)
    cfg = declared_sweep(world, PlanodomConfig())
    run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
    warm = world_fields(world, simulate_world(world, 0.0, n_epochs=3, all_fields=True))
    max_range = max(s.max_range for s in world.sensor_rig.sensors)
    period = 1.0 / world.epoch_rate
    for name in ("former", "cuts"):
        use(name, cuts, former)
        run_odometry(warm, cfg)
    kiss_icp_poses(warm.scans, period, max_range)
    cpu: dict[str, list[float]] = {"former": [], "cuts": [], "kiss": []}
    poses: dict[str, np.ndarray] = {}
    for _ in range(reps):
        for name in ("former", "cuts"):
            use(name, cuts, former)
            c0 = time.process_time()
            odo = run_odometry(run, cfg)
            cpu[name].append(time.process_time() - c0)
            poses[name] = np.asarray(odo.poses, dtype=np.float64)
        if not np.array_equal(poses["cuts"], poses["former"]):
            raise SystemExit(f"world {w}: the two variants' poses differ")
        c0 = time.process_time()
        kiss_icp_poses(run.scans, period, max_range)
        cpu["kiss"].append(time.process_time() - c0)
    use("cuts", cuts, former)
    ms = {name: 1e3 * min(v) / epochs for name, v in cpu.items()}
    return {"world": w, "kind": world.kind, **ms}


def main(cuts: tuple = CUTS, former: tuple = FORMER, doc: str = __doc__) -> None:
    """The A/B of ``former`` against ``cuts`` (this script's, or another release's)."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
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
        r = one_world(w, args.noise, args.epochs, args.reps, cuts, former)
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
