"""Loop closure on procedural worlds with closed routes (issue 14).

For each world (:func:`planodom.experiments.generalisation.world_for`) and range noise, one
lap is simulated (continuous motion) and compared, side by side:

- ``odometry``: planodom's delta = 1 odometry, chained, as the batch smoothing runs it
  (``smoothing.odometry_deskew_twist``; every smoothing row uses its planes and steps);
- ``windowed``: the fixed-lag smoother, relative poses delta = 1..D;
- ``windowed+loops``: the same with fixed-lag loop closure
  (:mod:`planodom.smoothing.windowed_loops`, ``smoothing.windowed_loop_closure``);
- ``batch``: the whole lap in one graph, no loop closure;
- ``batch+loops``: the same with the global plane map (:mod:`planodom.smoothing.loops`);
- ``batch+loops+redeskew``: with ``smoothing.redeskew_passes`` > 0 only, the same after
  that many passes deskewing the scans along the smoothed poses
  (:mod:`planodom.smoothing.redeskew`);
- ``oracle``: the oracle's pure odometry (:mod:`planodom.oracle`).

Per run: ATE (xy, origin-aligned, rmse), the xy position error at the loop's end (the last
epoch) and the height error there, for ``batch+loops`` the re-identifications kept,
removed by the gate, and wrong (joining true surfaces that are not coplanar: two segments
of one facade are one plane), the map matches the verification refused
(``smoothing.loop_verify``), the loop-candidate factors
(:mod:`planodom.smoothing.loop_candidates`) kept and removed, the kept ones wrong by the
truth (a component off by more than 3 of its sigmas) and the largest horizontal error of a
kept one, the mean NEES of the 5 observed DoF (chi2(5): 95 % interval
[0.83, 12.8]) and the model of its covariances (``covariance_model``: "sandwich" or
"fitted", ``smoothing.covariance_model`` "auto" resolved), the variance factors with
``smoothing.covariance_scale`` (:mod:`planodom.smoothing.variance_components`), and seconds.
``summary`` gives per noise and method the median and worst over the worlds, and the
loop-candidate factors kept and wrong over all of them, and the median epochs per second
(``windowed+loops`` also counts its ties and wrong ones, and the landmarks that re-entered
the window from their marginals).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.experiments.tables import ExperimentResult, write_tables
from planodom.geometry import Plane, invert_transform
from planodom.metrics import ate, pose_nees
from planodom.odometry import run_odometry
from planodom.odometry.relative import RelativePose
from planodom.oracle import run_oracle
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.batch import group_by_epoch, smooth_batch
from planodom.smoothing.loop_records import loop_factor_counts, reidentification_counts
from planodom.smoothing.run import run_smoothing, smoothing_config, smoothing_relatives
from planodom.smoothing.windowed import WindowedSmoother, smooth_windowed

METHODS = ("odometry", "windowed", "windowed+loops", "batch", "batch+loops",
           "batch+loops+redeskew", "oracle")  # fmt: skip
Row = dict[str, object]


def coplanar(scene, tol_deg: float = 2.0, tol_m: float = 0.1) -> Callable[[int, int], bool]:
    """``same_plane(a, b)`` for true surface ids of ``scene`` (unknown ids: True)."""
    planes = {s.id: np.append(s.normal, s.offset) for s in scene.surfaces}

    def same(a: int, b: int) -> bool:
        if a not in planes or b not in planes:
            return True
        pa, pb = planes[a], planes[b]
        if pa[:3] @ pb[:3] < 0:
            pb = -pb
        return bool(pa[:3] @ pb[:3] >= np.cos(np.radians(tol_deg)) and abs(pa[3] - pb[3]) <= tol_m)

    return same


def _errors(poses: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    end = float(np.linalg.norm(poses[-1][:2, 3] - gt[-1][:2, 3]))
    end_z = float(abs(poses[-1][2, 3] - gt[-1][2, 3]))
    return {"ate_m": ate(poses, gt, xy_only=True)["rmse"], "loop_end_m": end, "loop_end_z_m": end_z}


def _windowed_loops(
    planes: Sequence[Sequence[Plane]],
    relatives: Sequence[RelativePose],
    gt: np.ndarray,
    config: PlanodomConfig,
    same_plane: Callable[[int, int], bool] | None,
) -> Row:
    """The ``windowed+loops`` row: :func:`smooth_windowed` with fixed-lag loop closure, its
    ties (kept: the fixed-lag smoother has no gate) and re-entered landmarks."""
    smoother = WindowedSmoother(config.updated({"smoothing.windowed_loop_closure": True}))
    by_epoch = group_by_epoch(relatives, len(planes))
    for k, epoch_planes in enumerate(planes):
        smoother.add_epoch(epoch_planes, by_epoch[k])
    res = smoother.result()
    row: Row = {"method": "windowed+loops", **_errors(res.poses, gt), "seconds": res.runtime_s}
    if smoother.loops is not None:
        row |= reidentification_counts(smoother.loops.reidentifications, same_plane)
        row["reentered"] = smoother.loops.reentered
    return row


def compare_methods(
    planes: Sequence[Sequence[Plane]],
    relatives: Sequence[RelativePose],
    gt: np.ndarray,
    odometry_poses: np.ndarray,
    oracle_poses: np.ndarray | None,
    config: PlanodomConfig,
    same_plane: Callable[[int, int], bool] | None = None,
) -> list[Row]:
    """One row per method (see the module docstring) on one run's planes and relatives."""
    rows: list[Row] = [{"method": "odometry", **_errors(odometry_poses, gt)}]
    runs = (
        ("windowed", smooth_windowed, config.updated({"smoothing.windowed_loop_closure": False})),
        ("batch", smooth_batch, config.updated({"smoothing.loop_closure": False})),
        ("batch+loops", smooth_batch, config.updated({"smoothing.loop_closure": True})),
    )
    for method, smooth, cfg in runs:
        res = smooth(planes, relatives, cfg)
        row: Row = {"method": method, **_errors(res.poses, gt), "seconds": res.runtime_s}
        if method == "batch+loops":
            row |= reidentification_counts(res.reidentifications, same_plane)
            row |= loop_factor_counts(res.loop_factors, gt)
            row["matches_refused"] = sum(m.verdict != "accepted" for m in res.loop_matches)
            if res.covariances is not None:
                nees = pose_nees(res.poses[1:], res.covariances[1:], gt[1:], range(5))
                row["mean_nees5"] = float(np.nanmean(nees))
                row["covariance_model"] = res.covariance_model
            if res.variance_components is not None:  # smoothing.covariance_scale
                scales = res.variance_components.scales.items()
                row["variance_factors"] = " ".join(f"{k}={v:.3g}" for k, v in scales)
        rows.append(row)
        if method == "windowed":
            rows.append(_windowed_loops(planes, relatives, gt, config, same_plane))
    for row in rows[1:]:
        row["epochs_per_s"] = len(planes) / max(float(row["seconds"]), 1e-9)  # type: ignore[arg-type]
    if oracle_poses is not None:
        rows.append({"method": "oracle", **_errors(oracle_poses, gt)})
    return rows


def run_loop_world(
    index: int, noise: float, n_epochs: int | None, config: PlanodomConfig
) -> list[Row]:
    """Every method on one lap of world ``index`` at range noise ``noise`` (m)."""
    world = world_for(index)
    full = simulate_world(world, noise, n_epochs=n_epochs, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    odo = run_odometry(world_fields(world, full), smoothing_config(config))
    relatives = smoothing_relatives(odo, config)
    oracle = run_oracle(full.scans, full.times, world.trajectory, world.scene)
    same = coplanar(world.scene)
    rows = compare_methods(odo.planes, relatives, gt, odo.poses, oracle.poses, config, same)
    if config.smoothing.redeskew_passes:
        cfg = config.updated({"smoothing.loop_closure": True})
        run = run_smoothing(world_fields(world, full), cfg, mode="batch", odometry=odo)
        row: Row = {"method": "batch+loops+redeskew", **_errors(run.poses, gt)}
        seconds = sum(v for k, v in run.seconds.items() if k not in ("extraction", "odometry"))
        row["seconds"], row["epochs_per_s"] = seconds, len(odo.planes) / max(seconds, 1e-9)
        row |= reidentification_counts(run.result.reidentifications, same)
        row |= loop_factor_counts(run.result.loop_factors, gt)
        rows.insert(-1, row)
    for row in rows:
        row |= {"world": index, "family": world.description["family"], "noise_mm": noise * 1e3}
    return rows


def summary_rows(rows: Sequence[Row]) -> list[Row]:
    """Per noise and method: median and worst ATE and loop-end error, wrong closures."""
    out: list[Row] = []
    for noise in sorted({float(r["noise_mm"]) for r in rows}):  # type: ignore[arg-type]
        for method in METHODS:
            sel = [r for r in rows if r["noise_mm"] == noise and r["method"] == method]
            if not sel:
                continue
            a = np.array([r["ate_m"] for r in sel], dtype=float)
            e = np.array([r["loop_end_m"] for r in sel], dtype=float)
            wrong = sum(int(r.get("wrong_kept", 0)) for r in sel)  # type: ignore[call-overload]
            ties = sum(int(r.get("reidentified", 0)) for r in sel)  # type: ignore[call-overload]
            factors = sum(int(r.get("loop_factors", 0)) for r in sel)  # type: ignore[call-overload]
            wrong_factors = sum(int(r.get("loop_factors_wrong_kept", 0)) for r in sel)  # type: ignore[call-overload]
            rates = [float(r["epochs_per_s"]) for r in sel if "epochs_per_s" in r]  # type: ignore[arg-type]
            out.append(
                {
                    "noise_mm": noise,
                    "method": method,
                    "worlds": len(sel),
                    "median_ate_m": float(np.median(a)),
                    "worst_ate_m": float(a.max()),
                    "median_loop_end_m": float(np.median(e)),
                    "worst_loop_end_m": float(e.max()),
                    "ties_kept": ties,
                    "wrong_kept": wrong,
                    "loop_factors": factors,
                    "wrong_loop_factors": wrong_factors,
                    "median_epochs_per_s": float(np.median(rates)) if rates else float("nan"),
                }
            )
    return out


def run_loop_experiment(
    out: str | Path | None = None,
    worlds: Sequence[int] = range(6),
    noise_levels: Sequence[float] = (0.006, 0.02),
    n_epochs: int | None = None,
    config: PlanodomConfig | None = None,
    progress: Callable[[str], None] | None = None,
) -> ExperimentResult[Row]:
    """Run the comparison (``quick``: world 0, 6 mm, 120 epochs, from the CLI)."""
    cfg = config or PlanodomConfig()
    say = progress or (lambda msg: None)
    rows: list[Row] = []
    for index in worlds:
        for noise in noise_levels:
            say(f"world {index}, sigma {noise * 1e3:g} mm")
            start = time.perf_counter()
            rows += run_loop_world(index, noise, n_epochs, cfg)
            say(f"  {time.perf_counter() - start:.0f} s")
        if out is not None:  # the tables so far: an interrupted run keeps what it measured
            _tabulated(rows, Path(out))
    return _tabulated(rows, None if out is None else Path(out))


def _tabulated(rows: list[Row], out: Path | None) -> ExperimentResult[Row]:
    """The experiment's result from its rows so far, its tables written to ``out``."""
    keys = list(dict.fromkeys(k for r in rows for k in r))
    table = [{k: r.get(k, "") for k in keys} for r in rows]
    result = ExperimentResult(rows, {"runs": table, "summary": summary_rows(rows)})
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        result.files = write_tables(out, result.tables)
    return result
