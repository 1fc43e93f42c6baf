"""A what-if: the 2D rig's deskewing refinement without extracting the epoch again.

The streaming odometry extracts most 2D-rig epochs twice or more (docs/RESULTS.md,
RIG2DPASS, PASSES2CM): with the predicted twist, then with the epoch's own
(``odometry.deskew_iterations``). Each extraction costs about as much as the relative
pose after it. Here a refinement instead moves each plane of the estimate it refines to
first order by the plane's own deskewing Jacobian (``Plane.deskew_jacobian``,
``extraction.deskew_jacobian``: the change of ``(n, d)`` with the twist over the epoch's
span, :func:`planodom.extraction.planes.fit.deskew_jacobian`) and solves the relative
pose again on the moved planes: the same inlier sets, no new segmentation or grouping.
An estimate that was not deskewed (no twist) is refined by extracting it as before.

Runs ``planodom experiment generalisation``'s worlds (its tables in ``--out``) with

- ``default``: the default configuration (the reference);
- ``jacobian-off``: ``extraction.deskew_jacobian`` on, refinement unchanged (its outputs
  must equal the default's: the Jacobians are only carried);
- ``jacobian``: the Jacobians on and the refinement by them;

and prints each run's planodom CPU time an epoch (process time of ``run_odometry``).

    uv run --extra baselines python experiments/jacobian_refine.py --mode jacobian \\
        --first-world 180 --worlds 20 --noise 0.006 0.02 --epochs 150 --out OUT
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
import weakref  # noqa: E402
from typing import Any  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

import planodom.experiments.generalisation as gen  # noqa: E402
import planodom.extraction.planes.builder as builder_mod  # noqa: E402
import planodom.odometry.odometry as odo_mod  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.geometry import Plane  # noqa: E402
from planodom.odometry.kept_epoch import KeptEpoch  # noqa: E402
from planodom.planes import PlaneSet  # noqa: E402


def moved(plane: Plane, delta: np.ndarray) -> Plane:
    """``plane`` with ``(n, d)`` moved to first order by its deskewing Jacobian for the
    twist change ``delta`` (6,) over the epoch's span (rad, m); ``Plane`` normalises."""
    assert plane.deskew_jacobian is not None
    c = np.append(plane.normal, plane.offset) + plane.deskew_jacobian @ delta
    return Plane(
        normal=c[:3], offset=float(c[3]), covariance=plane.covariance,
        confidence=plane.confidence, support=plane.support, truth_id=plane.truth_id,
        deskew_jacobian=plane.deskew_jacobian,
    )  # fmt: skip


@numba.njit(cache=False)
def _jacobian_kernel(points, t, normal, c, evals, evecs):  # pragma: no cover - compiled
    """:func:`planodom.extraction.planes.fit.deskew_jacobian` with a given fit, compiled
    (the same formula; sums in another order, so not the same bits)."""
    sums = np.zeros((3, 6))
    for i in range(points.shape[0]):
        q0, q1, q2 = points[i, 0] - c[0], points[i, 1] - c[1], points[i, 2] - c[2]
        w = (
            t[i],
            t[i] * (q0 * evecs[0, 0] + q1 * evecs[1, 0] + q2 * evecs[2, 0]),
            t[i] * (q0 * evecs[0, 1] + q1 * evecs[1, 1] + q2 * evecs[2, 1]),
        )
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        cx = py * normal[2] - pz * normal[1]
        cy = pz * normal[0] - px * normal[2]
        cz = px * normal[1] - py * normal[0]
        for r in range(3):
            sums[r, 0] += w[r] * cx
            sums[r, 1] += w[r] * cy
            sums[r, 2] += w[r] * cz
            sums[r, 3] += w[r] * normal[0]
            sums[r, 4] += w[r] * normal[1]
            sums[r, 5] += w[r] * normal[2]
    out = np.zeros((4, 6))
    for a in range(3):
        for b in range(6):
            out[a, b] = -(evecs[a, 0] * sums[1, b]) / max(evals[0] - evals[2], 1e-300) - (
                evecs[a, 1] * sums[2, b]
            ) / max(evals[1] - evals[2], 1e-300)
    for b in range(6):
        out[3, b] = (
            -(c[0] * out[0, b] + c[1] * out[1, b] + c[2] * out[2, b])
            - sums[0, b] / (points.shape[0])
        )
    return out


def compiled_jacobian(points: np.ndarray, t: np.ndarray, normal: np.ndarray, fit: Any) -> Any:
    """The builder's ``deskew_jacobian`` call, compiled (:func:`_jacobian_kernel`)."""
    c, evals, evecs = fit
    return _jacobian_kernel(
        np.ascontiguousarray(points), np.ascontiguousarray(t), np.ascontiguousarray(normal),
        np.ascontiguousarray(c), np.ascontiguousarray(evals), np.ascontiguousarray(evecs),
    )  # fmt: skip


def patch_refinement(counts: dict[str, int], first_only: bool = False) -> None:
    """Replace the refinement's extraction (module docstring); ``counts`` counts the
    refinements done by the Jacobians and by extraction. ``first_only``: a refinement of
    an estimate the Jacobians gave is extracted (its own twist still asked for a change
    beyond the tolerances after one first-order step)."""
    real = odo_mod.PlaneOdometry._estimate_scan
    by_jacobian: weakref.WeakSet[Any] = weakref.WeakSet()  # the estimates the Jacobians gave

    def estimate_scan(
        self: Any, scan: Any, t: float, twist: Any, source: Any = None, prior_sigma: Any = None
    ) -> Any:
        planes = [] if source is None else source.planes
        usable = (
            source is not None and twist is not None and source.twist is not None
            and scan.t is not None and len(scan.t) and len(planes)
            and all(p.deskew_jacobian is not None for p in planes)
            and not (first_only and source in by_jacobian)
        )  # fmt: skip
        if not usable:
            if source is not None:
                counts["extracted"] += 1
            return real(self, scan, t, twist, source, prior_sigma)
        counts["jacobian"] += 1
        span = float(np.max(np.abs(scan.t)))
        delta = (np.asarray(twist, dtype=np.float64) - source.twist) * span
        new = [moved(p, delta) for p in planes]
        used = np.array(twist, dtype=np.float64)
        epoch = KeptEpoch(len(self.poses), new, PlaneSet.from_planes(new), scan, used)
        out = self._estimate(epoch, t)
        if first_only:
            by_jacobian.add(out)
        return out

    odo_mod.PlaneOdometry._estimate_scan = estimate_scan  # type: ignore[method-assign]


def time_runs(cpu: list[tuple[int, float]]) -> None:
    """Record the process time and epochs of every ``run_odometry`` the experiment makes."""
    real = gen.run_odometry

    def timed(source: Any, config: Any, *a: Any, **k: Any) -> Any:
        c0 = time.process_time()
        out = real(source, config, *a, **k)
        cpu.append((len(out.poses), time.process_time() - c0))
        return out

    gen.run_odometry = timed  # type: ignore[assignment]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--mode", choices=("default", "jacobian-off", "jacobian", "jacobian-first"),
        required=True,
    )  # fmt: skip
    ap.add_argument("--first-world", type=int, default=180)
    ap.add_argument("--worlds", type=int, default=20)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--methods", default="planodom")
    ap.add_argument("--out", required=True)
    ap.add_argument(
        "--compiled", action="store_true",
        help="the planes' Jacobians by a compiled kernel (what a library version would cost)",
    )  # fmt: skip
    args = ap.parse_args()
    cfg = PlanodomConfig()
    if args.mode != "default":
        cfg = cfg.updated({"extraction.deskew_jacobian": True}, source="jacobian_refine")
    counts = {"jacobian": 0, "extracted": 0}
    if args.mode.startswith("jacobian") and args.mode != "jacobian-off":
        patch_refinement(counts, first_only=args.mode == "jacobian-first")
        if args.compiled:
            builder_mod.deskew_jacobian = compiled_jacobian  # type: ignore[assignment]
    cpu: list[tuple[int, float]] = []
    time_runs(cpu)
    say = lambda msg: print(msg, flush=True)  # noqa: E731
    gen.run_generalisation_experiment(
        args.out, args.worlds, args.noise, args.epochs, args.methods.split(","), cfg, say,
        ("rig2d",), args.first_world,
    )  # fmt: skip
    runs = [(n, s) for n, s in cpu if n == args.epochs]  # not the warm-up's
    for n, s in runs:
        print(f"cpu ms/epoch {1e3 * s / n:.3f}")
    print(f"refinements by Jacobian {counts['jacobian']}, by extraction {counts['extracted']}")


if __name__ == "__main__":
    main()
