"""Mean NEES5 of a lap's batch with loops, ``smoothing.sandwich_loop_sources``
"independent" against "shared" and "deskew" (the same poses; issue 14, NEES2CM, NEESJAC).

The lap and its odometry as ``nees_gauge.py`` (``--cache DIR`` reuses the odometry), the
batch with loops once with the default config but "independent"; its covariances then
computed again from the same graph and estimate with the option "shared", then "deskew",
then (a diagnostic, "apart") "deskew"'s maps in a column of their own per older epoch, and
(diagnostics, "first", "first_deskew") "independent" and "deskew" with the first epoch's
``Q_0`` its first step's declared covariance (:func:`_first_step`); "step" (NEESFIRST)
``smoothing.sandwich_first_epoch`` "step" with independent loop factors, "step_shared" and
"step_deskew" with those loop sources, "degenerate_step" that value; "both" (NEES6)
``smoothing.sandwich_relative_ends`` "both"; "both_loops", "both_steps" (diagnostics)
its maps of the loop factors alone or of the steps alone; "loops" (LOOP0)
``smoothing.sandwich_relative_ends`` "loops" (the option for "both_loops"); "epoch" (NEESRUN)
``smoothing.sandwich_motion_scale`` "epoch", "epoch_both" that with "both",
"epoch_shared" (a diagnostic) that with ``sandwich_loop_sources`` "shared", "epoch_keep0"
and "epoch0_only" (diagnostics) "epoch" but at the first epoch, or only there; ``--modes``
picks.
Printed per lap: ATE (xy rmse, m), mean NEES5 each way, the loop factors and the older
epochs they come from, and for "deskew" the loop factors given a map and the mean of
``tr(g Q_a g^T) / dim`` (the added whitened variance against the factor's own, 1).

    uv run python experiments/loop_sources_nees.py --world 148 --noise 0.02 --cache DIR

``--time N``: the covariances (``batch_covariances`` on the captured graph and estimate)
computed N times each way, alternating independent / ``--timed`` (default "deskew"),
process time per call.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import gtsam
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402  (patches the batch to capture its graph)

from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.smoothing import batch_covariances, sandwich  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.batch_covariances import covariance_graph  # noqa: E402
from planodom.smoothing.loop_deskew import loop_deskew_maps  # noqa: E402
from planodom.smoothing.loop_sources import loop_error_maps, loop_source_maps  # noqa: E402
from planodom.smoothing.relative_deskew import relative_error_maps  # noqa: E402
from planodom.smoothing.sandwich import covariance_graph_index  # noqa: E402


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--time", type=int, default=0, help="repeats of the CPU timing")
    parser.add_argument("--timed", default="deskew", help="the option value timed")
    parser.add_argument("--modes", default="shared,deskew,apart,first,first_deskew")
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    cfg = cfg.updated({"smoothing.sandwich_loop_sources": "independent"})
    res = smooth_batch(odo.planes, rel, cfg)
    assert res.covariances is not None, res.covariance_note
    cap = nees_gauge.CAPTURED
    builder = cap["builder"]
    on = cfg.updated({"smoothing.sandwich_loop_sources": "shared"}).smoothing
    cov_graph = covariance_graph(
        cap["graph"], cap["gaussian"], cap["estimate"], on.covariance_inlier_quantile
    )
    maps, cols = loop_source_maps(cov_graph, len(gt), on.delta_max)
    xi = pose_errors(res.poses, gt)
    ate = float(np.sqrt(np.mean(np.sum(xi[:, 3:5] ** 2, axis=1))))
    nees = {"independent": np.nanmean(errors_nees(xi[1:], res.covariances[1:], range(5)))}
    for mode in args.modes.split(","):
        value = {"apart": "deskew", "first": "independent", "first_deskew": "deskew"}
        value = value.get(mode, mode)
        changes = {"smoothing.sandwich_loop_sources": value}
        if mode.startswith("step"):  # NEESFIRST: smoothing.sandwich_first_epoch "step"
            changes = {"smoothing.sandwich_loop_sources": mode[5:] or "independent",
                       "smoothing.sandwich_first_epoch": "step"}  # fmt: skip
        if mode.startswith("both"):  # NEES6: smoothing.sandwich_relative_ends "both"
            changes = {"smoothing.sandwich_loop_sources": "independent",
                       "smoothing.sandwich_relative_ends": "both"}  # fmt: skip
        if mode == "loops":  # LOOP0: smoothing.sandwich_relative_ends "loops"
            changes = {"smoothing.sandwich_loop_sources": "independent",
                       "smoothing.sandwich_relative_ends": "loops"}  # fmt: skip
        if mode in ("epoch", "epoch_both"):  # NEESRUN: sandwich_motion_scale "epoch"
            changes = {"smoothing.sandwich_loop_sources": "independent",
                       "smoothing.sandwich_motion_scale": "epoch",
                       "smoothing.sandwich_relative_ends": mode[6:] or "none"}  # fmt: skip
        if mode == "epoch_shared":  # NEESRUN diagnostic: with sandwich_loop_sources shared
            changes = {"smoothing.sandwich_loop_sources": "shared",
                       "smoothing.sandwich_motion_scale": "epoch"}  # fmt: skip
        if mode in EPOCH_SPLITS:
            changes = {"smoothing.sandwich_loop_sources": "independent"}
        if mode == "degenerate_step":
            changes = {"smoothing.sandwich_loop_sources": "independent",
                       "smoothing.sandwich_first_epoch": "degenerate_step"}  # fmt: skip
        builder.config = cfg.updated(changes).smoothing
        sandwich.loop_error_maps = _apart if mode == "apart" else loop_error_maps
        sandwich.relative_error_maps = RELATIVE_KINDS.get(mode, relative_error_maps)
        first = mode.startswith("first")
        batch_covariances.sandwich_inputs = _first_step if first else SANDWICH_INPUTS
        if mode in EPOCH_SPLITS:  # NEESRUN diagnostics: "epoch" and "run" mixed at epoch 0
            batch_covariances.sandwich_inputs = EPOCH_SPLITS[mode]
        _, P_on, note, _, model = nees_gauge.ORIGINAL(
            builder, cap["graph"], cap["gaussian"], cap["fallback"], cap["estimate"],
            cap["n"], cap["planes"], cap["rel"],
        )  # fmt: skip
        assert P_on is not None, note
        nees[mode] = np.nanmean(errors_nees(xi[1:], P_on[1:], range(5)))
    batch_covariances.sandwich_inputs = SANDWICH_INPUTS
    sandwich.loop_error_maps = loop_error_maps
    sandwich.relative_error_maps = relative_error_maps
    Q = nees_gauge.CAPTURED_Q()
    index = covariance_graph_index(cap["graph"], cov_graph)
    dmaps = loop_deskew_maps(
        cov_graph, cap["estimate"], builder.loop_factors, index, builder.planes, Q
    )
    share = [np.trace(g @ Q[a] @ g.T) / len(g) for a, g in dmaps.values()] or [0.0]
    print(f"world {args.world} noise {args.noise} epochs {len(gt)} ATE(body xy) {ate:.4f} "
          f"model {model} loop factors {len(maps)} from {len(cols)} epochs "
          f"NEES5 independent {nees['independent']:.2f} "
          + " ".join(f"{m} {v:.2f}" for m, v in nees.items() if m != "independent")
          + f" (maps {len(dmaps)}, mean added "
          f"{np.mean(share):.3g}, max {max(share):.3g})")  # fmt: skip
    if args.time:
        key = "relative_ends" if args.timed == "both" else "loop_sources"
        key = "motion_scale" if args.timed == "epoch" else key
        timed = cfg.updated({f"smoothing.sandwich_{key}": args.timed}).smoothing
        _time_covariances(builder, cfg.smoothing, timed, cap, args.time)


SANDWICH_INPUTS = batch_covariances.sandwich_inputs


def _kind(loops: bool):  # noqa: ANN202
    """A diagnostic ("both_loops", "both_steps"): "both"'s maps of the loop factors (two
    poses beyond ``delta_max``) alone, or of the steps alone."""

    def maps(cov_graph, values, Q, delta_max, *args):  # noqa: ANN001, ANN002, ANN202
        out = relative_error_maps(cov_graph, values, Q, delta_max, *args)
        gap = {i: np.ptp([gtsam.Symbol(k).index() for k in cov_graph.at(i).keys()]) for i in out}
        return {i: t for i, t in out.items() if (gap[i] > delta_max) == loops}

    return maps


RELATIVE_KINDS = {"both_loops": _kind(True), "both_steps": _kind(False)}


def _first_step(cfg, planes, relative_poses, n_epochs):  # noqa: ANN001, ANN202
    """A diagnostic ("first", "first_deskew"): the sandwich's inputs with the first epoch's
    ``Q_0`` the first step's declared covariance times ``(span / interval)^2`` (it was
    deskewed with that step's twist: its error is the step's)."""
    Q, why = SANDWICH_INPUTS(cfg, planes, relative_poses, n_epochs)
    step = next((r for r in relative_poses if r.delta == 1 and r.curr == 1 and r.measured), None)
    if step is None:
        raise SystemExit("--modes first*: this lap's first step (0 -> 1) was not measured")
    lo, hi = step.deskew_times or (0.0, step.interval_s)
    var = np.append(np.diag(np.asarray(step.covariance, dtype=float).reshape(5, 5)), 0.0)
    var[5] = step.sigma_z**2 if step.z_observed and np.isfinite(step.sigma_z) else 0.0
    Q = np.array(Q, copy=True)
    Q[0] = np.diag(var * (max(abs(lo), abs(hi)) / step.interval_s) ** 2)
    return Q, why


def _epoch_split(first_from_epoch: bool):  # noqa: ANN202
    """A diagnostic ("epoch_keep0", "epoch0_only"): the sandwich's inputs with
    ``sandwich_motion_scale`` "epoch" in every epoch but the first (its "run" ``Q_0``), or
    "run" in every epoch but the first (its "epoch" ``Q_0``)."""

    def inputs(cfg, planes, relative_poses, n_epochs):  # noqa: ANN001, ANN202
        run, why = SANDWICH_INPUTS(cfg, planes, relative_poses, n_epochs)
        epoch_cfg = cfg.model_copy(update={"sandwich_motion_scale": "epoch"})
        epoch, _ = SANDWICH_INPUTS(epoch_cfg, planes, relative_poses, n_epochs)
        assert run is not None and epoch is not None
        out = np.array(run if first_from_epoch else epoch, copy=True)
        out[0] = epoch[0] if first_from_epoch else run[0]
        return out, why

    return inputs


EPOCH_SPLITS = {"epoch_keep0": _epoch_split(False), "epoch0_only": _epoch_split(True)}


def _apart(mode, cov_graph, values, Q, delta_max, index, loops):  # noqa: ANN001, ANN202
    """A diagnostic: "deskew"'s maps, each older epoch in a column of its own (a copy of
    its ``Q_a``) instead of its plane factors' (the loop factors' share uncorrelated
    with them)."""
    out = loop_error_maps(mode, cov_graph, values, Q, delta_max, index, loops)
    assert out is not None
    maps = out[0]
    olders = sorted({a for a, _ in maps.values()})
    column = {a: len(Q) + j for j, a in enumerate(olders)}
    apart = {i: (column[a], g) for i, (a, g) in maps.items()}
    return apart, np.stack([Q[a] for a in olders]) if olders else np.zeros((0, 6, 6))


def _time_covariances(builder, off, on, cap, repeats: int) -> None:  # noqa: ANN001
    """Process time of the batch's covariances, independent and ``on``, alternating."""
    times: dict[str, list[float]] = {"independent": [], "on": []}
    for _ in range(repeats):
        for name, config in (("independent", off), ("on", on)):
            builder.config = config
            t0 = time.process_time()
            nees_gauge.ORIGINAL(
                builder, cap["graph"], cap["gaussian"], cap["fallback"], cap["estimate"],
                cap["n"], cap["planes"], cap["rel"],
            )  # fmt: skip
            times[name].append(time.process_time() - t0)
    off_t, on_t = np.median(times["independent"]), np.median(times["on"])
    print(f"covariance CPU s (median of {repeats}) independent {off_t:.2f} "
          f"{on.sandwich_loop_sources}/{on.sandwich_relative_ends}/{on.sandwich_motion_scale} "
          f"{on_t:.2f} "
          f"ratio {on_t / off_t:.3f}; all: {times}")  # fmt: skip


if __name__ == "__main__":
    main()
