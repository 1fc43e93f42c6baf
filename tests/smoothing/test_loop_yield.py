"""The joint test of a loop hypothesis and the map ties it contradicts
(planodom.smoothing.loop_yield), on one 1-D variable in closed form.

Variable x (a Point3, only its first coordinate constrained); the loop hypothesis pulls it
to 10 m (sigma 0.1 m), a tie to 0 m (sigma 0.1 m). Where the rest of the graph is weak
(sigma 100 m) the tie is all that contradicts the loop: without it the loop passes, so
the tie yields. Where the rest is firm at 0 m the loop still fails: nothing yields.
"""

from __future__ import annotations

from types import SimpleNamespace

import gtsam
import numpy as np
import pytest
from scipy.stats import chi2

from planodom.config import PlanodomConfig
from planodom.smoothing.loop_records import Reidentification
from planodom.smoothing.loop_yield import contradicted, yield_ties

KEY = gtsam.symbol("x", 0)


def _prior(x: float, sigma: float) -> gtsam.NonlinearFactor:
    """A prior on the first coordinate of KEY (the others held at 0 by a stiff prior)."""
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([sigma, 1e-3, 1e-3]))
    return gtsam.PriorFactorPoint3(KEY, np.array([x, 0.0, 0.0]), noise)


def _problem(rest_sigma: float):
    """Graph: [rest at 0, tie at 0 (epoch 5), loop at 10]; builder with the tie's record."""
    graph = gtsam.NonlinearFactorGraph()
    for f in (_prior(0.0, rest_sigma), _prior(0.0, 0.1), _prior(10.0, 0.1)):
        graph.add(f)
    tie = Reidentification(epoch=5, plane=0, landmark=1, factor=1)
    builder = SimpleNamespace(
        config=PlanodomConfig().smoothing,
        reidentifications=[tie],
        stats=SimpleNamespace(reidentified_removed=0),
    )
    return graph, builder, tie


def _values(x: float) -> gtsam.Values:
    values = gtsam.Values()
    values.insert(KEY, np.array([x, 0.0, 0.0]))
    return values


def test_a_tie_is_contradicted_when_its_error_rises_beyond_chi2_3():
    graph, builder, tie = _problem(100.0)
    limit = chi2.ppf(builder.config.loop_gate_quantile, 3)
    # the tie's squared whitened error: (x / 0.1)^2; from x = 0 to x: 100 x^2
    just_below, just_above = np.sqrt(0.99 * limit / 100), np.sqrt(1.01 * limit / 100)
    assert contradicted(builder, graph, {}, _values(just_below), _values(0.0)) == []
    assert contradicted(builder, graph, {}, _values(just_above), _values(0.0)) == [tie]
    tie.removed = True  # a removed tie is no longer weighed
    assert contradicted(builder, graph, {}, _values(just_above), _values(0.0)) == []


@pytest.mark.parametrize(("rest_sigma", "yields"), [(100.0, True), (0.1, False)])
def test_the_tie_yields_only_when_the_loop_then_passes(rest_sigma, yields):
    graph, builder, tie = _problem(rest_sigma)
    # the estimate with the loop (the tie and the loop compromise at 5 m, the weak rest
    # too) and the optimum without it (all at 0 m)
    estimate, alone = _values(5.0), _values(0.0)
    limit = chi2.ppf(builder.config.loop_gate_quantile, 5)
    removed, increase = yield_ties(builder, graph, {}, estimate, alone, {2}, {2}, limit)
    # without the tie: the rest alone against the loop at 10 m, solved in closed form
    x = 10.0 * 0.1**-2 / (0.1**-2 + rest_sigma**-2)
    assert increase == pytest.approx((x / rest_sigma) ** 2, rel=1e-6)
    assert (removed == 1) is yields and tie.removed is yields
    assert graph.at(1) is None if yields else graph.at(1) is not None
    assert builder.stats.reidentified_removed == int(yields)
