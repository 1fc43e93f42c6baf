"""``smoothing.loop_gate_parts``: a loop hypothesis that fails the chi2 gate weighed
against the map's parts (planodom.smoothing.loop_gate_parts), on a constructed lap.

A corridor lap of 40 epochs (positions, Point3; x out to 20 m and back, y and z held):
the truth ``x_k = k`` up to epoch 20, ``40 - k`` after. Odometry between consecutive
epochs: the true step plus seeded noise (sigma 5 cm, Gaussian). The map ties each epoch
k of 28-31 (part A, right) and 34-37 (part B, wrong: one wall spacing, 3 m, off along the
corridor, as a map's wrong correction carries its ties) to the old epoch ``40 - k`` at
the same place (sigma 2 cm, Gaussian, as a tie of a landmark without anchor). Part A's
first match takes the first correction, part B's first a new one (both full rank, the
rest rotation-only). The loop hypothesis: epochs 38 and 39 against 2 and 1 (robust,
sigma 2 cm), right, or (second case) 3 m off with a right map.

The wrong part's eight stiff ties outweigh the robust closure in the solve, so the chi2
gate removes the right closure and the map keeps its 3 m error (the default). With the
option the part's removal lets the closure fit, and the bent odometry it spares makes
its robust chi2 per degree of freedom the lower: the wrong ties go, the closure stays,
and the estimate is checked against the truth. A wrong closure against a right map is
still removed: there, removing it is the hypothesis that fits.
"""

from __future__ import annotations

from types import SimpleNamespace

import gtsam
import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.smoothing.batch import _gated, levenberg_marquardt
from planodom.smoothing.loop_gate import loop_start
from planodom.smoothing.loop_gate_parts import degrees_of_freedom
from planodom.smoothing.loop_records import LoopFactor, LoopMatch, Reidentification

N, ALIAS_M = 40, 3.0
TRUTH = np.array([k if k <= 20 else 40 - k for k in range(N)], dtype=float)
HELD = 1e-3  # y, z sigma: the lap is one-dimensional


def _noise(sigma: float) -> gtsam.noiseModel.Base:
    return gtsam.noiseModel.Diagonal.Sigmas(np.array([sigma, HELD, HELD]))


def _between(i: int, j: int, dx: float, noise: gtsam.noiseModel.Base) -> gtsam.NonlinearFactor:
    return gtsam.BetweenFactorPoint3(i, j, np.array([dx, 0.0, 0.0]), noise)


def _match(k: int, shift: float, full: bool, new: bool) -> LoopMatch:
    """An accepted map match at epoch k (its correction only counts for the split)."""
    T = np.eye(4)
    T[0, 3] = shift
    cov = np.eye(5) * 1e-4
    mahalanobis = 100.0 if new else 1.0
    return LoopMatch(k, 0, T, np.eye(4), cov, np.zeros((3, 3)), mahalanobis, [], full=full)


def _lap(closure_off_m: float, alias_m: float):
    """(builder, graph, gaussian, initial values): the module docstring's lap, part B
    ``alias_m`` and the closure ``closure_off_m`` off along x."""
    rng = np.random.default_rng(7)
    graph, gaussian = gtsam.NonlinearFactorGraph(), {}
    graph.add(gtsam.PriorFactorPoint3(0, np.zeros(3), _noise(1e-3)))
    steps = np.diff(TRUTH) + 0.05 * rng.standard_normal(N - 1)
    for k in range(1, N):
        graph.add(_between(k - 1, k, steps[k - 1], _noise(0.05)))
    ties, matches = [], []
    for part, epochs, shift in (("A", range(28, 32), 0.0), ("B", range(34, 38), alias_m)):
        for n, k in enumerate(epochs):
            matches.append(_match(k, shift, full=n == 0, new=n == 0))
            for _ in range(2):  # two walls per epoch
                dx = TRUTH[k] - TRUTH[40 - k] + shift + 0.02 * rng.standard_normal()
                label = 1 if part == "A" else 2  # its truth: which part
                ties.append(Reidentification(k, 0, 40 - k, graph.size(), label, label))
                graph.add(_between(40 - k, k, dx, _noise(0.02)))
    cauchy = gtsam.noiseModel.mEstimator.Cauchy.Create(2.3849)
    loops = []
    for k, old in ((38, 2), (39, 1)):
        dx = TRUTH[k] - TRUTH[old] + closure_off_m
        loops.append(LoopFactor(k, old, np.eye(4), np.eye(5) * 4e-4, 3, graph.size(), 0))
        gaussian[graph.size()] = _between(old, k, dx, _noise(0.02))
        graph.add(_between(old, k, dx, gtsam.noiseModel.Robust.Create(cauchy, _noise(0.02))))
    values = gtsam.Values()
    for k, x in enumerate(np.concatenate([[0.0], np.cumsum(steps)])):  # the chained odometry
        values.insert(k, np.array([x, 0.0, 0.0]))
    builder = SimpleNamespace(
        config=PlanodomConfig().smoothing,
        loop_factors=loops,
        matches=matches,
        reidentifications=ties,
        stats=SimpleNamespace(reidentified_removed=0),
    )
    return builder, graph, gaussian, values


def _run(parts: str, closure_off_m: float = 0.0, alias_m: float = ALIAS_M):
    """(estimate's x (N,), loop factors kept, ties removed of part A, of part B)."""
    builder, graph, gaussian, values = _lap(closure_off_m, alias_m)
    builder.config = PlanodomConfig().updated({"smoothing.loop_gate_parts": parts}).smoothing
    cfg = builder.config
    start = loop_start(builder, graph, gaussian, values)
    estimate = levenberg_marquardt(graph, start, cfg.max_iterations, cfg.relative_error_tol)[0]
    estimate = _gated(builder, graph, gaussian, values, estimate, [])
    x = np.array([estimate.atPoint3(k)[0] for k in range(N)])
    ties = builder.reidentifications
    removed = [sum(r.removed for r in ties if r.truth_landmark == t) for t in (1, 2)]
    return x, sum(not f.removed for f in builder.loop_factors), *removed


def test_the_default_gate_removes_the_right_closure_and_keeps_the_wrong_part():
    x, kept, removed_a, removed_b = _run("off")
    assert (kept, removed_a, removed_b) == (0, 0, 0)
    assert np.max(np.abs(x - TRUTH)) > 1.0  # the wrong part bends the lap's end


@pytest.mark.parametrize("parts", ["corrections", "matches"])
def test_the_option_removes_the_wrong_part_and_keeps_the_closure(parts):
    x, kept, removed_a, removed_b = _run(parts)
    assert (kept, removed_a, removed_b) == (2, 0, 8)
    # against the truth: the odometry's noise alone (steps of 5 cm between the lap's
    # ties), far below the alias the default keeps
    assert np.max(np.abs(x - TRUTH)) < 0.1 * ALIAS_M


@pytest.mark.parametrize("parts", ["off", "corrections"])
def test_a_wrong_closure_against_a_right_map_is_still_removed(parts):
    x, kept, removed_a, removed_b = _run(parts, closure_off_m=ALIAS_M, alias_m=0.0)
    assert (kept, removed_a, removed_b) == (0, 0, 0)
    assert np.max(np.abs(x - TRUTH)) < 0.1 * ALIAS_M


def test_degrees_of_freedom_count_residuals_less_variables():
    graph = gtsam.NonlinearFactorGraph()
    graph.add(gtsam.PriorFactorPoint3(0, np.zeros(3), _noise(1.0)))
    graph.add(_between(0, 1, 1.0, _noise(1.0)))
    graph.add(_between(0, 1, 1.0, _noise(1.0)))
    values = gtsam.Values()
    values.insert(0, np.zeros(3))
    values.insert(1, np.zeros(3))
    assert degrees_of_freedom(graph, values) == 9 - 6
    graph.remove(2)
    assert degrees_of_freedom(graph, values) == 0
