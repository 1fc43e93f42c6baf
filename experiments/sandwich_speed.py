"""The sandwich covariances' dense path against its sparse selected inversion, and the
fitted covariances' time, on the same linearised batch-with-loops graph.

Per lap (``WORLD:NOISE``, as ``experiments/sandwich_nees.py``): the batch with loop
closure and ``smoothing.covariance_model: sandwich`` is run up to its covariances; then
the fitted covariances (:func:`.marginals.pose_covariances`), the dense sandwich and the
sparse one are timed twice, alternating their order, and the largest difference of the
sparse from the dense path is printed in units of the standard deviations (sandwich and
fitted blocks; also gtsam's fitted blocks against the dense path's).

    uv run python experiments/sandwich_speed.py 8:0.006 14:0.02
"""

from __future__ import annotations

import argparse
import time

import gtsam
import numpy as np

import planodom.smoothing.batch as batch_module
import planodom.smoothing.batch_covariances as covariances_module
import planodom.smoothing.sandwich as sw
import planodom.smoothing.sparse_sandwich as ssw
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.graph import X
from planodom.smoothing.marginals import FIRST_POSE_TIGHTENING, pose_covariances
from planodom.smoothing.run import smoothing_config, smoothing_relatives


class _Captured(Exception):
    pass


def _capture(world_index: int, noise: float) -> tuple:
    """(config, graph, covariance graph, plane factors, Q, estimate) of the lap's batch."""
    cfg = PlanodomConfig().updated(
        {"smoothing.loop_closure": True, "smoothing.covariance_model": "sandwich"}
    )
    world = world_for(world_index)
    full = simulate_world(world, noise, all_fields=True)
    odo = run_odometry(world_fields(world, full), smoothing_config(cfg))
    got: dict[str, tuple] = {}

    def hook(*args: object) -> None:
        got["args"] = args
        raise _Captured

    original = covariances_module.batch_sandwich
    covariances_module.batch_sandwich = hook  # type: ignore[assignment]
    try:
        batch_module.smooth_batch(odo.planes, smoothing_relatives(odo, cfg), cfg)
    except _Captured:
        pass
    finally:
        covariances_module.batch_sandwich = original
    return got["args"]


def _worst(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| over poses 1.. in units of b's standard deviations."""
    sd = np.sqrt(np.einsum("kii->ki", b))
    return float(np.nanmax(np.abs(a - b)[1:] / (sd[1:, :, None] * sd[1:, None, :])))


def run(world_index: int, noise: float) -> None:
    cfg, graph, cov_graph, planes, Q, estimate = _capture(world_index, noise)
    index = sw.covariance_graph_index(graph, cov_graph)
    zero = estimate.zeroVectors()
    dims = {key: zero.at(key).size for key in estimate.keys()}
    maps = {}
    for i, (epoch, plane) in planes.items():
        if i in index:
            g = sw.plane_error_map(cov_graph.at(index[i]), plane)
            if g is not None and np.any(Q[epoch]):
                maps[index[i]] = (epoch, g)
    keys = [X(k) for k in range(len(Q))]

    def linear() -> gtsam.GaussianFactorGraph:
        lin = cov_graph.linearize(estimate)
        stiff = FIRST_POSE_TIGHTENING / cfg.prior_sigma
        lin.add(X(0), stiff * np.eye(6), np.zeros(6), gtsam.noiseModel.Unit.Create(6))
        return lin

    times: dict[str, list[float]] = {"fitted": [], "dense": [], "sparse": []}
    out: dict[str, object] = {}
    for rep in range(2):
        for name in ("fitted", "dense", "sparse")[:: 1 if rep % 2 == 0 else -1]:
            start = time.perf_counter()
            if name == "fitted":
                out[name] = pose_covariances(cov_graph, estimate, len(Q), True, cfg.prior_sigma)[0]
            elif name == "dense":
                out[name] = sw._dense_pose_covariances(linear(), keys, dims, maps, Q)
            else:
                out[name] = ssw.sparse_pose_covariances(linear(), keys, dims, maps, Q)
            times[name].append(time.perf_counter() - start)
    dense, sparse = out["dense"], out["sparse"]
    assert isinstance(dense, sw.SandwichMarginals) and isinstance(sparse, tuple)
    med = {k: float(np.median(v)) for k, v in times.items()}
    print(
        f"world {world_index} noise {noise} epochs {len(Q)}: sparse - dense in sd: sandwich "
        f"{_worst(sparse[0], dense.covariances):.2e}, fitted {_worst(sparse[1], dense.fitted):.2e} "
        f"(gtsam's fitted - dense {_worst(np.asarray(out['fitted']), dense.fitted):.2e}); "
        f"seconds fitted {times['fitted']} dense {times['dense']} sparse {times['sparse']}; "
        f"sparse / fitted {med['sparse'] / med['fitted']:.2f}, dense / fitted "
        f"{med['dense'] / med['fitted']:.2f}",
        flush=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("laps", nargs="+", help="WORLD:NOISE, e.g. 14:0.02")
    for lap in parser.parse_args().laps:
        world, noise = lap.split(":")
        run(int(world), float(noise))


if __name__ == "__main__":
    main()
