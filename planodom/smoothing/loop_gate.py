"""Loop hypotheses after optimisation (issue 14): the graduated start, the chi2 gate and the
likelihood-ratio test of the loop-candidate factors of
:class:`planodom.smoothing.loop_candidates.CandidateLoopBuilder`."""

from __future__ import annotations

import gtsam
import numpy as np
from scipy.stats import chi2

from planodom.smoothing.loop_records import LoopFactor


def loop_start(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
) -> gtsam.Values:
    """Starting values for the robust solve: ``values`` optimised with the kept loop
    factors Gaussian (graduated: from a prediction metres off, a robust kernel would
    treat right loop factors as outliers and never close the loop), or ``values`` as
    they are without loop factors."""
    from planodom.smoothing.batch import levenberg_marquardt  # (batch imports this module)

    factors = [f.factor for f in getattr(builder, "loop_factors", []) if not f.removed]
    if not factors:
        return values
    loops = set(factors)
    convex = gtsam.NonlinearFactorGraph()
    for i in range(graph.size()):
        if graph.at(i) is not None:
            convex.add(gaussian[i] if i in loops else graph.at(i))
    cfg = builder.config  # type: ignore[attr-defined]
    return levenberg_marquardt(convex, values, cfg.max_iterations, cfg.relative_error_tol)[0]


def gate_loop_factors(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
) -> int:
    """Remove the loop factors (of a :class:`CandidateLoopBuilder`; none for other
    builders) whose squared whitened error at ``values`` exceeds the
    ``loop_gate_quantile`` of chi2(5) from ``graph`` (and their Gaussian twins); returns
    how many, with every factor of their hypotheses (``LoopFactor.group``: chained
    agreeing poses; a wrong hypothesis may fit in part once it has pulled the estimate).
    Each factor's chi2 is recorded."""
    factors: list[LoopFactor] = getattr(builder, "loop_factors", [])
    if not factors:
        return 0
    limit = float(chi2.ppf(builder.config.loop_gate_quantile, 5))  # type: ignore[attr-defined]
    failed = set()
    for f in factors:
        if not f.removed:
            f.chi2 = 2.0 * float(gaussian.get(f.factor, graph.at(f.factor)).error(values))
            if f.chi2 > limit:
                failed.add(f.group)
    removed = 0
    for f in factors:
        if not f.removed and f.group in failed:  # one hypothesis: all its factors out
            graph.remove(f.factor)
            gaussian.pop(f.factor, None)
            f.removed = True
            removed += 1
    return removed


def _without(
    graph: gtsam.NonlinearFactorGraph, drop: set[int], gaussian: dict[int, gtsam.NonlinearFactor]
) -> gtsam.NonlinearFactorGraph:
    """``graph`` without the factors ``drop`` (indices); Gaussian twins where given."""
    out = gtsam.NonlinearFactorGraph()
    for i in range(graph.size()):
        if i not in drop and graph.at(i) is not None:
            out.add(gaussian.get(i, graph.at(i)))
    return out


def test_hypotheses(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
    estimate: gtsam.Values,
) -> int:
    """A likelihood-ratio test of each kept loop hypothesis (``LoopFactor.group``).

    The rest of the graph (every factor but the loop factors, with their robust kernels:
    the Gaussian twins of outlier factors would swamp the difference) is evaluated at
    ``estimate`` and at the optimum without the hypothesis (solved from ``estimate``). A
    right loop closure costs the rest what the drift it corrects costs; a wrong one bends
    a well-measured map. The
    hypothesis is removed (from ``graph``) when the increase, in squared whitened units,
    exceeds the ``loop_gate_quantile`` of chi2(5 x its factors). Returns how many were."""
    from planodom.smoothing.batch import levenberg_marquardt  # (batch imports this module)

    factors: list[LoopFactor] = [f for f in getattr(builder, "loop_factors", []) if not f.removed]
    cfg = builder.config  # type: ignore[attr-defined]
    loops = {f.factor for f in factors}
    removed = 0
    for group in sorted({f.group for f in factors if np.isnan(f.increase)}):  # once each
        mine = {f.factor for f in factors if f.group == group}
        rest = _without(graph, loops, {})
        others = _without(graph, mine, {})
        # from the estimate: the hypothesis's removal relaxes it (one solve, not two)
        alone = levenberg_marquardt(others, estimate, cfg.max_iterations, cfg.relative_error_tol)[0]
        increase = 2.0 * (rest.error(estimate) - rest.error(alone))
        limit = chi2.ppf(cfg.loop_gate_quantile, 5 * len(mine))
        for f in factors:
            if f.group == group:
                f.increase = float(increase)
        if increase > limit:
            for f in factors:
                if f.group == group:
                    graph.remove(f.factor)
                    gaussian.pop(f.factor, None)
                    f.removed = True
                    removed += 1
    return removed
