"""The plane builder's two compiled calls against its former stage sequence, in one process.

The 2D rig's default odometry runs each world's simulated run with the builder as it is
(:mod:`planodom.extraction.planes.passes`: two compiled calls) and with the stage
sequence it replaced (``fit_arrays``, ``Epoch.viewpoints``, ``mean_incidences``, the
orientation kernel, ``distinct_and_majority``, ``support_polygons``, one wrapper each,
:func:`former_build_planes` below), alternating, ``--reps`` times each after an untimed
warm-up of both, and KISS-ICP on the same scans (as ``bench_rig2d_vs_kiss.py`` runs it).
The fastest repetition of each counts (process time: the machine's load moves wall time
by more than the difference). Per world: both variants' CPU ms an epoch, their ratio,
KISS-ICP's, and planodom's epochs/s as a multiple of KISS-ICP's with each variant; the
poses of the two variants must be the same bits (checked on every repetition). One
process, so no second copy of the package (SPEED2D6 found two copies in one process
slow each other's numba dispatch).

    uv run --extra baselines python experiments/bench_plane_builder.py --noise 0.02 \\
        --epochs 150 --worlds 160 162 164 168 170 172 --reps 5
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

import planodom.extraction.rig2d.path as rig2d_path  # noqa: E402
from planodom.config import ExtractionConfig, PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.experiments.peers import kiss_available, kiss_icp_poses  # noqa: E402
from planodom.extraction.epoch import Epoch  # noqa: E402
from planodom.extraction.planes import builder  # noqa: E402
from planodom.extraction.planes.builder import _COS45, Adjust, PlaneFits  # noqa: E402
from planodom.extraction.planes.confidence import cpef, mean_incidences  # noqa: E402
from planodom.extraction.planes.fit import fit_arrays  # noqa: E402
from planodom.extraction.planes.passes import _orientation_kernel  # noqa: E402
from planodom.extraction.planes.support import (  # noqa: E402
    distinct_and_majority,
    support_polygons,
)
from planodom.geometry import Plane, PlaneSupport  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402


def former_build_planes(
    fits: PlaneFits, epoch: Epoch, sigma_m: float, config: ExtractionConfig,
    adjust: Adjust | None = None, narrow: np.ndarray | None = None,
) -> tuple[list[Plane], list[np.ndarray], int]:  # fmt: skip
    """:func:`planodom.extraction.planes.builder.build_planes` as it was before SPEED2D7
    (one wrapper and one compiled call per stage), for the default configuration (no
    deskewing Jacobian, no time moments, ``viewpoint_planes`` not ``rejected``, no
    narrow planes: ``narrow`` is not used)."""
    G = len(fits)
    if G == 0:
        return [], [], 0
    normals = fits.evecs[:, :, 2]
    floor = config.covariance_sigma_floor_m
    max_var_n = float(np.radians(config.max_normal_sigma_deg) ** 2)
    covs, width, rms, keep, scatter = fit_arrays(
        fits.evals, fits.evecs, fits.centroid, fits.count, floor**2,
        config.min_plane_points, config.min_plane_width_m, max_var_n,
    )  # fmt: skip
    kept = np.flatnonzero(keep)
    height = config.viewpoint_height_m
    views = np.zeros((G, 3))
    views[:, 2] = height
    incidence = np.ones(G) if fits.incidence is None else fits.incidence.copy()
    if fits.incidence is None or epoch.origins is not None:
        inl, bnd = fits.inliers.astype(np.int64), fits.bounds.astype(np.int64)
        views[kept] = epoch.viewpoints(inl, bnd, kept, height)
        incidence[kept] = mean_incidences(epoch.points, inl, bnd, kept, views[kept], normals[kept])
    signs = _orientation_kernel(normals, fits.offset, fits.centroid, views, _COS45)
    conf = cpef(
        rms, max(sigma_m, floor), fits.count, width, incidence,
        config.confidence_points_ref, config.confidence_width_ref_m,
    )  # fmt: skip
    n_or = signs[:, None] * normals
    d_or = signs * fits.offset
    if adjust is not None and len(kept):
        kept = adjust(kept, n_or, d_or)
    planes, inliers = [], []
    rows, truth = distinct_and_majority(
        epoch.scan.ring if fits.n_rows is None else None, epoch.scan.label, fits.inliers,
        fits.bounds, kept,
    )  # fmt: skip
    polygons = support_polygons(
        epoch.points, fits.inliers, fits.bounds, fits.outline, kept, fits.centroid, fits.evecs
    )
    n_rows_all = (rows if fits.n_rows is None else fits.n_rows[kept]).tolist()
    count, offset, confidence = fits.count.tolist(), d_or.tolist(), conf.tolist()
    starts, truths = fits.bounds.tolist(), truth.tolist()
    for k, g in enumerate(kept.tolist()):
        idx = fits.inliers[starts[g] : starts[g + 1]]
        centroid = fits.centroid[g]
        seen = (centroid.copy(), polygons[k], count[g], scatter[g], int(n_rows_all[k]))
        plane = Plane(
            normal=n_or[g], offset=offset[g], covariance=covs[g], confidence=confidence[g],
            support=PlaneSupport(*seen, None), truth_id=int(truths[k]),
        )  # fmt: skip
        planes.append(plane)
        inliers.append(idx)
    return planes, inliers, G - len(kept)


VARIANTS = {"passes": builder.build_planes, "former": former_build_planes}


def one_world(w: int, noise: float, epochs: int, reps: int) -> dict:
    """CPU ms an epoch (best of ``reps``) of both variants and KISS-ICP on world ``w``."""
    world = world_for(w)
    cfg = declared_sweep(world, PlanodomConfig())
    ext = cfg.extraction
    if ext.deskew_jacobian or ext.time_moments or ext.viewpoint_planes == "rejected":
        raise SystemExit("former_build_planes covers the default builder options only")
    run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
    warm = world_fields(world, simulate_world(world, 0.0, n_epochs=3, all_fields=True))
    max_range = max(s.max_range for s in world.sensor_rig.sensors)
    period = 1.0 / world.epoch_rate
    for fn in VARIANTS.values():
        rig2d_path.build_planes = fn
        run_odometry(warm, cfg)
    kiss_icp_poses(warm.scans, period, max_range)
    cpu: dict[str, list[float]] = {name: [] for name in (*VARIANTS, "kiss")}
    poses: dict[str, np.ndarray] = {}
    for _ in range(reps):
        for name, fn in VARIANTS.items():
            rig2d_path.build_planes = fn
            c0 = time.process_time()
            odo = run_odometry(run, cfg)
            cpu[name].append(time.process_time() - c0)
            poses[name] = np.asarray(odo.poses, dtype=np.float64)
        if not np.array_equal(poses["passes"], poses["former"]):
            raise SystemExit(f"world {w}: the two builders' poses differ")
        c0 = time.process_time()
        kiss_icp_poses(run.scans, period, max_range)
        cpu["kiss"].append(time.process_time() - c0)
    rig2d_path.build_planes = builder.build_planes
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
    shares = []
    for w in args.worlds:
        r = one_world(w, args.noise, args.epochs, args.reps)
        share = r["passes"] / r["former"]
        shares.append(share)
        print(
            f"world {w:3d} {r['kind']:7s} | former {r['former']:6.2f} passes "
            f"{r['passes']:6.2f} ratio {share:.3f} | KISS-ICP {r['kiss']:6.2f} | x KISS-ICP: "
            f"former {r['kiss'] / r['former']:.3f} passes {r['kiss'] / r['passes']:.3f}",
            flush=True,
        )
    print(f"median passes / former: {np.median(shares):.3f} ({len(shares)} worlds)")


if __name__ == "__main__":
    main()
