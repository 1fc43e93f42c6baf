"""The chi2 gate's joint test of a failing loop hypothesis against the map's parts
(``smoothing.loop_gate_parts``, issue 14).

The gate (:func:`.loop_gate.gate_loop_factors`) removes a loop hypothesis one of whose
factors' squared whitened error exceeds chi2(5) at ``loop_gate_quantile`` after the
solve. Either the hypothesis is wrong, or the map holds wrong plane ties that it
contradicts: after a wrong full-rank match the map's tracked correction carries every
later tie along with it (2D-rig world 32 at 2 cm: the ties after the matches at epochs
609 and 917 are 3.4 and 6.3 m off, docs/RESULTS.md GATE32, SPLIT32), and in a corridor
the solve bends to fit both, the right closure left at chi2 5-68. Here the two
explanations are weighed. The map is split into parts as ``loop_map_parts`` splits its
clique node (:func:`.loop_map_parts.split_at_corrections`; "corrections" or "matches",
this option's value). The hypotheses:

- H0: the loop hypothesis is wrong. The graph without its factors, solved.
- H_p, for each part p whose ties conflict with the loop hypothesis (one of its ties'
  squared whitened error rises by more than chi2(3) at ``loop_gate_quantile`` from the
  solve of H0 to the gate's estimate solved again with the hypothesis's factors Gaussian,
  :func:`.loop_yield.contradicted`, :func:`pulled_by`): the part is
  wrong. The graph without the part's ties, the loop hypothesis kept, solved; eligible
  only if every factor of the loop hypothesis then passes the gate (the closure alone
  fits).

Each is solved as the batch solves after a gate round (from the initial values, loop
factors Gaussian first, then robust, :func:`.loop_gate.loop_start`). The one kept is the
one of least robust chi2 per degree of freedom, ``2 E / (m - n)``: ``E`` the graph's
error at its solve (robust kernels: 0.5 sum of the kernels' losses), ``m`` its factors'
residual dimensions, ``n`` the variables' tangent dimensions. Why per degree of
freedom: the hypotheses leave out different measurements (5 per loop factor, 3 per
plane tie), and a left-out measurement that fits lowers the chi2 by about its own
dimensions, so the raw likelihood always favours leaving out more. Divided by the
degrees of freedom, leaving out right measurements changes the score by about nothing
in expectation, leaving out wrong ones lowers it: the hypothesis that removes what
does not fit wins, whatever its size. No truth is used. If H_p wins, the part's ties
go (marked ``removed``) and the loop hypothesis stays for the next round's gate and
likelihood-ratio test; else the hypothesis goes, as without this option.

At most :data:`MAX_PARTS` conflicting parts are tried per failing hypothesis, those
with the largest total rise first (each is two solves of the whole graph).

Measured (docs/RESULTS.md, W32C): on world 32 at 2 cm (the odometry with
``odometry.z_offset_measured_only`` off) "corrections" keeps the right closure (loop end
3.70 -> 0.013 m) by removing the map's first part, 726 ties of which 6 were wrong. The
part wins on its own misfit (1.63 chi2 per dimension against the plane factors' 1.39, the
plane covariances being too small), not on what the closure adds (0.0008 per degree of
freedom), and without it two aliased loop hypotheses pass (29 wrong loop factors kept).
Hence off.

Written here, not taken from a library: gtsam has the solves, not this decision.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np
from scipy.stats import chi2

from planodom.smoothing.loop_gate import gate_loop_factors, map_hypothesis
from planodom.smoothing.loop_map_parts import split_at_corrections
from planodom.smoothing.loop_records import LoopFactor, Reidentification
from planodom.smoothing.loop_yield import contradicted

#: Conflicting parts tried per failing loop hypothesis (two solves of the graph each).
MAX_PARTS = 6


@dataclass
class PartHypothesis:
    """One explanation of a failing loop hypothesis (module docstring).

    Attributes:
        ties: the plane ties it removes (empty: H0, the loop hypothesis removed).
        score: robust chi2 per degree of freedom at its solve (inf: not eligible).
        loop_chi2: the loop hypothesis's factors' squared whitened errors at its solve
            (empty for H0).
        rise: the part's ties' total rise of squared whitened error (0 for H0).
    """

    ties: list[Reidentification]
    score: float
    loop_chi2: list[float]
    rise: float = 0.0


def degrees_of_freedom(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> int:
    """Residual dimensions of ``graph``'s factors minus the tangent dimensions of
    ``values`` (the variables ``graph`` solves)."""
    m = sum(graph.at(i).dim() for i in range(graph.size()) if graph.at(i) is not None)
    return int(m - values.dim())


def solve_without(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
    drop: set[int],
) -> tuple[gtsam.Values, float]:
    """``graph`` without the factors ``drop`` (indices) solved from ``values`` as the batch
    solves after a gate round (kept loop factors Gaussian first); returns the estimate and
    its robust chi2 per degree of freedom (module docstring)."""
    from planodom.smoothing.batch import levenberg_marquardt  # (batch imports this module)

    cfg = builder.config  # type: ignore[attr-defined]
    factors: list[LoopFactor] = getattr(builder, "loop_factors", [])
    loops = {f.factor for f in factors if not f.removed} - drop
    convex, robust = gtsam.NonlinearFactorGraph(), gtsam.NonlinearFactorGraph()
    for i in range(graph.size()):
        if graph.at(i) is not None and i not in drop:
            convex.add(gaussian[i] if i in loops else graph.at(i))
            robust.add(graph.at(i))
    start = values
    if loops:
        start = levenberg_marquardt(convex, values, cfg.max_iterations, cfg.relative_error_tol)[0]
    estimate = levenberg_marquardt(robust, start, cfg.max_iterations, cfg.relative_error_tol)[0]
    dof = max(degrees_of_freedom(robust, estimate), 1)
    return estimate, 2.0 * float(robust.error(estimate)) / dof


def pulled_by(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    estimate: gtsam.Values,
    mine: set[int],
) -> gtsam.Values:
    """``graph`` solved from ``estimate`` with the loop factors ``mine`` (indices) Gaussian:
    where the loop hypothesis pulls the map when it is not let give in (its robust kernel
    does give in where stiff ties outnumber it, and then no tie's error rises)."""
    from planodom.smoothing.batch import levenberg_marquardt  # (batch imports this module)

    cfg = builder.config  # type: ignore[attr-defined]
    pulled = gtsam.NonlinearFactorGraph()
    for i in range(graph.size()):
        if graph.at(i) is not None:
            pulled.add(gaussian[i] if i in mine else graph.at(i))
    return levenberg_marquardt(pulled, estimate, cfg.max_iterations, cfg.relative_error_tol)[0]


def conflicting_parts(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    estimate: gtsam.Values,
    alone: gtsam.Values,
) -> list[tuple[list[Reidentification], float]]:
    """The map's parts (``loop_gate_parts``'s split) one of whose ties conflicts with the
    loop hypothesis (:func:`.loop_yield.contradicted` between ``alone``, the solve
    without it, and ``estimate``, with it, :func:`pulled_by`): each part's kept ties and
    their total rise of squared whitened error (Gaussian twins), the largest rise first."""
    cfg = builder.config  # type: ignore[attr-defined]
    matches, ties = map_hypothesis(builder)
    if not ties:
        return []
    parts = split_at_corrections(
        matches, ties, cfg.loop_gate_quantile, cfg.loop_gate_parts == "matches"
    )
    hit = {r.factor for r in contradicted(builder, graph, gaussian, estimate, alone)}
    out = []
    for _, part in parts:
        if hit & {r.factor for r in part}:
            rise = 0.0
            for r in part:
                f = gaussian.get(r.factor, graph.at(r.factor))
                rise += 2.0 * (float(f.error(estimate)) - float(f.error(alone)))
            out.append((part, rise))
    return sorted(out, key=lambda p: -p[1])


def weigh_parts(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
    estimate: gtsam.Values,
    group: int,
) -> list[PartHypothesis]:
    """H0 and the H_p of the failing loop hypothesis ``group`` (module docstring), solved
    from the initial ``values``; ``estimate`` the gate's. H0 first."""
    cfg = builder.config  # type: ignore[attr-defined]
    factors: list[LoopFactor] = getattr(builder, "loop_factors", [])
    mine = {f.factor for f in factors if f.group == group and not f.removed}
    alone, score = solve_without(builder, graph, gaussian, values, mine)
    out = [PartHypothesis([], score, [])]
    limit = float(chi2.ppf(cfg.loop_gate_quantile, 5))
    pulled = pulled_by(builder, graph, gaussian, estimate, mine)
    for part, rise in conflicting_parts(builder, graph, gaussian, pulled, alone)[:MAX_PARTS]:
        drop = {r.factor for r in part}
        solved, score = solve_without(builder, graph, gaussian, values, drop)
        fits = [2.0 * float(gaussian.get(i, graph.at(i)).error(solved)) for i in sorted(mine)]
        out.append(PartHypothesis(part, score if max(fits) <= limit else np.inf, fits, rise))
    return out


def gate_loops(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
    estimate: gtsam.Values,
) -> int:
    """The chi2 gate of the loop factors at ``estimate``, with ``loop_gate_parts`` not
    "off" weighed against the map's parts (module docstring): returns how many factors
    were removed, loop factors or plane ties (from ``graph`` and ``gaussian``, marked
    ``removed``). The failing hypotheses are weighed largest first; the first whose
    H_p wins has that part's ties removed and the rest wait for the next round (solved
    again first); those whose H0 wins are removed as the gate removes them."""
    cfg = builder.config  # type: ignore[attr-defined]
    factors: list[LoopFactor] = getattr(builder, "loop_factors", [])
    if cfg.loop_gate_parts == "off" or not factors or cfg.loop_gate_removes == "factor":
        return gate_loop_factors(builder, graph, gaussian, estimate)
    limit = float(chi2.ppf(cfg.loop_gate_quantile, 5))
    failed: dict[int, int] = {}
    for f in factors:
        if not f.removed:
            f.chi2 = 2.0 * float(gaussian.get(f.factor, graph.at(f.factor)).error(estimate))
            if f.chi2 > limit:
                failed[f.group] = sum(g.group == f.group and not g.removed for g in factors)
    removed = 0
    for group in sorted(failed, key=lambda g: (-failed[g], g)):
        weighed = weigh_parts(builder, graph, gaussian, values, estimate, group)
        best = min(weighed, key=lambda h: h.score)
        drop: list = best.ties or [f for f in factors if f.group == group and not f.removed]
        for r in drop:
            graph.remove(r.factor)
            gaussian.pop(r.factor, None)
            r.removed = True
        removed += len(drop)
        if best.ties:
            builder.stats.reidentified_removed += len(best.ties)  # type: ignore[attr-defined]
            return removed
    return removed
