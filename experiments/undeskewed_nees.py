"""The sandwich covariances with and without the undeskewed epochs' motion (issue 14).

For each world and range noise, one lap simulated as ``planodom experiment loops``, the
odometry run once as ``planodom smooth`` runs it, the batch with loops once (default
config: "auto" covariances, the sandwich on these laps), and its covariances computed
again at the same estimate with ``smoothing.sandwich_undeskewed`` "none" (the previous
release) and "motion" (:mod:`planodom.smoothing.undeskewed`). Per run: epochs, epochs
kept without deskewing, xy ATE (origin-aligned, as ``planodom experiment loops``), mean
NEES5 (chi2(5), 95 % per run [0.83, 12.8]) of both, and of both over the undeskewed
epochs and the others.

    uv run python experiments/undeskewed_nees.py --worlds 22 --levels 0.02 -o OUT.csv
"""

from __future__ import annotations

import argparse

import numpy as np

import planodom.smoothing.batch as batch_module
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate, errors_nees, pose_errors
from planodom.odometry import run_odometry
from planodom.results import write_rows
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.batch_covariances import covariance_graph, sandwich_inputs
from planodom.smoothing.run import smoothing_config, smoothing_relatives
from planodom.smoothing.sandwich import batch_sandwich
from planodom.smoothing.undeskewed import undeskewed_errors

CAPTURED: dict = {}
_ORIGINAL = batch_module.batch_covariances


def _spy(builder, graph, gaussian, fallback, estimate, n, planes=None, rel=()):  # noqa: ANN001, ANN202, PLR0913
    out = _ORIGINAL(builder, graph, gaussian, fallback, estimate, n, planes, rel)
    CAPTURED.update(builder=builder, graph=graph, gaussian=gaussian, estimate=out[0],
                    n=n, planes=planes or {}, rel=rel)  # fmt: skip
    return out


batch_module.batch_covariances = _spy


def covariances(cfg: PlanodomConfig) -> np.ndarray:
    """(E, 6, 6) the batch's sandwich covariances at the captured estimate under ``cfg``."""
    s = cfg.smoothing
    c = CAPTURED
    Q, _ = sandwich_inputs(s, c["planes"], c["rel"], c["n"])
    assert Q is not None
    cov_graph = covariance_graph(c["graph"], c["gaussian"], c["estimate"],
                                 s.covariance_inlier_quantile)  # fmt: skip
    return batch_sandwich(s, c["graph"], cov_graph, c["planes"], Q, c["estimate"])[0]


def run(world_index: int, noise: float, changes: dict | None = None) -> dict:
    """One lap (``changes``: further config keys, dotted, for both runs)."""
    world = world_for(world_index)
    full = simulate_world(world, noise, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    base = PlanodomConfig().updated({"smoothing.loop_closure": True} | (changes or {}))
    odo = run_odometry(world_fields(world, full), smoothing_config(base))
    rel = smoothing_relatives(odo, base)
    res = batch_module.smooth_batch(odo.planes, rel, base)
    kept = np.all(np.isfinite(undeskewed_errors(rel, len(gt))), axis=1)
    xi = pose_errors(res.poses, gt)
    row: dict = {
        "world": world_index,
        "noise_mm": noise * 1e3,
        "epochs": len(gt),
        "undeskewed": int(kept.sum()),
        "ate_m": float(ate(res.poses, gt, xy_only=True)["rmse"]),
        "model": res.covariance_model,
    }
    for mode in ("none", "motion"):
        cov = covariances(base.updated({"smoothing.sandwich_undeskewed": mode}))
        if mode == base.smoothing.sandwich_undeskewed:  # the batch's own
            assert res.covariances is not None and np.allclose(cov, res.covariances)
        n5 = errors_nees(xi[1:], cov[1:], range(5))
        row[f"nees5_{mode}"] = float(np.nanmean(n5))
        row[f"nees5_{mode}_undeskewed"] = float(np.nanmean(n5[kept[1:]])) if kept.any() else np.nan
        row[f"nees5_{mode}_others"] = float(np.nanmean(n5[~kept[1:]]))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", default="20,22")
    parser.add_argument("--levels", default="0.006,0.02")
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE",
        help="a further config key, e.g. extraction.own_scan_plane=trimmed",
    )  # fmt: skip
    parser.add_argument("-o", "--out", required=True)
    args = parser.parse_args()
    changes = dict(item.split("=", 1) for item in args.set)
    rows = []
    for w in [int(x) for x in args.worlds.split(",")]:
        for noise in [float(x) for x in args.levels.split(",")]:
            rows.append(run(w, noise, changes) | {"set": " ".join(args.set)})
            print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in rows[-1].items()},
                  flush=True)  # fmt: skip
            write_rows(args.out, rows)


if __name__ == "__main__":
    main()
