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

from typing import Any  # noqa: E402

# SPEED2D8's runner (this script runs beside it in experiments/), with this release's cuts
import bench_glue_cuts  # noqa: E402
import numpy as np  # noqa: E402

import planodom.odometry.refine as refine  # noqa: E402
import planodom.odometry.solver as solver  # noqa: E402
import planodom.odometry.translation as translation  # noqa: E402
from planodom.odometry.solver_glue import (  # noqa: E402
    numpy_near_rows,
    numpy_pair_ids,
    numpy_remapped_pairs,
)


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
CUTS = bench_glue_cuts.cuts_of(FORMER)


def use(variant: str) -> None:
    """Put the ``variant``'s functions in place ("cuts" or "former")."""
    bench_glue_cuts.use(variant, CUTS, FORMER)


if __name__ == "__main__":
    bench_glue_cuts.main(CUTS, FORMER, __doc__)
