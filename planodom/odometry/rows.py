"""The per-epoch rows of an odometry run (``epochs.csv``): status, increment, sigmas and
the solver's diagnostics."""

from __future__ import annotations

from typing import TYPE_CHECKING

from planodom.odometry.relative import RelativePose, Status

if TYPE_CHECKING:
    from planodom.odometry.run import OdometryRun

_POSE5 = ("roll", "pitch", "yaw", "x", "y")


def epoch_rows(run: OdometryRun) -> list[dict[str, object]]:
    """One dict per epoch (``epochs.csv``): time, status, the 5-DoF increment, sigmas and
    the solver's diagnostics."""
    out: list[dict[str, object]] = []
    for k, r in enumerate(run.results):
        row: dict[str, object] = {"epoch": k, "time": float(run.times[k])}
        row["n_planes"] = int(run.n_planes[k])
        if r is None:
            row["status"] = "first"
            out.append(row)
            continue
        row["status"] = str(r.status)
        row |= {name: float(v) for name, v in zip(_POSE5, r.pose5, strict=True)}
        row["z"] = float(r.T_prev_curr[2, 3])
        row["z_observed"] = r.z_observed
        row |= {f"sigma_{name}": float(v) for name, v in zip(_POSE5, r.sigmas5, strict=True)}
        row |= _diagnostic_columns(r)
        row["fallback"] = r.status is Status.UNRESOLVED
        row["inconsistent"] = r.inconsistent
        out.append(row)
    return out


def _diagnostic_columns(r: RelativePose) -> dict[str, object]:
    info = r.diagnostics
    rc = info.rotation_consensus if info else None
    tc = info.translation_consensus if info else None
    return {
        "n_lda_pairs": len(info.lda) if info else 0,
        "n_sda": len(r.associations),
        "n_translation_pairs": info.n_translation_pairs if info else 0,
        "rotation_error": rc.best_error if rc else float("nan"),
        "rotation_inliers": rc.n_inliers if rc else 0,
        "translation_error": tc.best_error if tc else float("nan"),
        "translation_inliers": tc.n_inliers if tc else 0,
        "used_prior": info.used_prior if info else False,
    }
