"""Configuration of batch loop closure's loop candidates and loop hypotheses (a part of
:class:`planodom.config.smoothing.SmoothingConfig`, planodom.smoothing.loop_candidates)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from planodom.config.odometry import Positive
from planodom.config.tie_gate import TieGateConfig
from planodom.errors import ConfigError

#: A probability or fraction in (0, 1].
Fraction = Annotated[float, Field(gt=0, le=1)]


class LoopCandidateConfig(TieGateConfig):
    """Loop candidates (5-DoF loop factors between revisited epochs), their hypotheses and
    the gate after optimisation; fields of the ``smoothing`` section."""

    loop_candidates: bool = True
    """Batch, with ``loop_closure``: also relative poses between the current epoch and old
    epochs within reach of its predicted pose (planodom.smoothing.loop_candidates): the
    paper's odometry under bounds grown from the chained covariance, verified by its
    strict (consensus) associations, added as robust 5-DoF between factors and checked
    by chi2(5) after optimisation."""
    loop_candidate_drift: Literal["chained", "stated", "run"] = "run"
    """The drift a loop candidate must agree within, with the previous verified one and with
    the map's accepted correction (chi2(3)): "chained" as the map matches' verification
    (the fallback's yaw variance for rotation-only epochs, a half of the fallback's
    translation variance per axis), "stated" as the odometry states it (their measured
    yaw, the fallback's sigma on each axis), "run": as "chained", but a bridged epoch adds
    the error of the run's own constant velocity (a random walk as large per epoch as the
    run's measured consecutive steps changed, :class:`planodom.smoothing.loop_drift.RunWalk`),
    in the candidates' bounds too, and before the map has accepted a correction a loop
    pose's must lie within it. As that drift the fallback factor's 0.5 m per epoch let
    aliased places through: on 2D-rig world 16 at 6 mm (coplanar deskewing) 72 bridged
    epochs (true drift 0.45 m) made room for a corridor aliased 4.6 m along, 21 wrong
    loop factors were kept (ATE 3.06 m; "run": 0.019 m)."""
    loop_drift_yaw: Literal["fallback", "run"] = "fallback"
    """With ``loop_candidate_drift`` "run": the yaw variance a bridged epoch (no relative
    pose measured even its rotation) adds to that drift: "fallback" the fallback factor's
    (``fallback_rotation_sigma_rad``, 2.9 deg per epoch), "run" the error of the run's own
    constant yaw rate, a random walk as large per epoch as its measured consecutive yaw
    steps changed (:class:`planodom.smoothing.loop_drift.RunWalk`), at most the fallback's.
    Alone (one lap of the 2D-rig worlds 0, 2, .., 18, batch with loops): world 6 at 6 mm
    0.078 -> 0.053 m, the other 19 runs within 1 mm (world 12 at 2 cm 0.0359 -> 0.0361 m)
    (loop end of world 6 3.7 -> 4.2 and 0.5 -> 2.8 cm). Off: one run of 20 is weak evidence."""
    loop_verify_drift: Literal["chained", "run"] = "chained"
    """The drift a map match's correction must agree within (``loop_verify``, chi2(3) with
    the accepted correction or the pending one): "chained" the chained odometry's, the
    fallback factor's sigmas for a bridged epoch; "run" the loop candidates' (needs
    ``loop_candidate_drift`` "run" and ``loop_candidates``; with ``loop_drift_yaw``). Why:
    with ``relative_prior: measured_steps`` on 2D-rig world 2 at 6 mm a match 2.3 m off
    along a corridor (its along-track sigma 0.19 m) passed under the chained drift (1.79 m:
    the fallback's 0.05 rad per bridged epoch over 14 m; the guess was 0.19 m off), and the
    tracked correction then walked to 5.5 m: 89 wrong ties and 6 loop factors 7.8 m off
    kept, ATE 3.64 m; under the run's (0.26 m, both "run") it is refused: 0.035 m. Both
    "run" on the ten laps at 6 mm and 2 cm: world 4 at 2 cm 0.069 -> 0.052 m, world 16 at
    6 mm 0.025 -> 0.021, world 2 at 6 mm 0.0347 -> 0.0343, but world 6 at 6 mm 0.078 ->
    0.110 m (its last epoch's map match, 3.1 m off along a corridor, is refused; a loop
    factor 18 cm off comes instead, gated, and the solve ends elsewhere); medians 0.0133 ->
    0.0133 and 0.0506 -> 0.0441 m, no wrong tie either way. Off: world 6."""
    loop_candidate_every_epochs: Annotated[int, Field(ge=1)] = 1  # every N-th epoch only
    loop_candidate_radius_m: Positive = 4.0
    """An old epoch is a candidate within this (m) plus the drift's translation bound."""
    loop_candidate_max: Annotated[int, Field(ge=1)] = 5
    """Old epochs tried per attempt (the nearest, ``loop_candidate_every_epochs`` apart)."""
    loop_candidate_old: Literal["any", "translated"] = "any"
    """Old epochs a loop candidate may tie to; "translated": only those whose planes gave a
    measured translation with a neighbour (delta <= D) (see docs/RESULTS.md). Measured again on one
    lap of the 2D-rig worlds 0, 2, .., 18 (batch with loops, this default otherwise): loop
    end below 10 cm on every world at 6 mm (world 18 10.5 -> 2.1 cm, ATE 0.050 -> 0.025 m;
    at 2 cm 11.5 -> 3.5 cm, 0.065 -> 0.048 m), the rest within 1 mm at 6 mm; but at 2 cm
    world 6 0.253 -> 3.02 m and world 10 0.024 -> 0.102 m (no loop factor: every old epoch
    their loop poses verify at is untranslated). Off (unchanged with ``loop_verify_drift``)."""
    loop_candidate_min_inliers: Annotated[int, Field(ge=2)] = 3
    """Strict associations (with non-parallel normals) a loop candidate needs (3: the
    2D rig's epochs hold 4-6 planes; a revisit matches the ground and two walls)."""
    loop_candidate_overlap_m: Positive = 1.0
    """The supports (spheres of centroid and radius) of each plane pair a loop candidate
    associates must come within this of each other under its relative pose, m."""
    loop_candidate_aliases: Literal["off", "both_epochs", "spacing"] = "both_epochs"
    """Refuse a loop candidate whose association is ambiguous: "both_epochs" when one
    tie's plane swapped for another wall parallel to it (same orientation, its offset
    beyond the two planes' noise: not the wall extracted twice) in the old or in the
    current epoch, the pose shifted to fit, costs at most chi2(1) at
    ``loop_gate_quantile`` more under the prediction's prior (``loop_sigmas`` of the
    candidate's drift bound), level planes left out (they place x, y by their tilt only)
    (:func:`.match_fit.epoch_ambiguity`); that epoch then tries no further old epochs
    (they see less of the place, not more). "spacing": also the tie moved by that
    spacing the other way (a wall neither epoch shows, where parallel walls repeat).
    "off": no test (``loop_refuse_ambiguous`` not "off" tries the old epoch's walls).
    Why (2D-rig world 32, held out, 6 mm): the loop pose's position along a corridor
    rests on one wall across it, one of a row 3.05-3.17 m apart, and the prediction is
    4.5-4.7 m off (sd 3.2-7 m): at 788 the current epoch sees the right wall and its
    neighbour and tied the neighbour (3.8 m off), at 851-873 epoch 0 shows two of the
    row and the tie went to the wrong one (3.5 m off); 28 such factors outnumbered the
    right 15 in the clique (ATE 1.456 m, loop end 4.24 m). "both_epochs": 0.304 m, loop
    end 1.41 m, wrong plane ties kept 3 -> 0, loop factors kept all within 2 cm (the
    right closures at 785-787, ambiguous too, go as well). Every other run of one lap of
    the even worlds 0-38 at 6 mm and 2 cm (batch with loops) is unchanged to the digit,
    loop factors included; world 32 at 2 cm stays 3.28 m (its 118 wrong map ties).
    Where it falls short: a match neither of whose epochs shows a second wall of the
    row passes (world 32's 792-795, 4 factors 3.8 m off, removed by the clique).
    "spacing" gives the same 40 runs to the digit: no gain for more refusals."""
    loop_candidate_confirm_epochs: Annotated[int, Field(ge=1)] = 10
    """A verified loop candidate becomes a factor only when the previous verified one,
    at most this many epochs before, implies the same correction of the chained guess
    (chi2(3) at ``loop_gate_quantile``); then both do. Two far apart agree on anything:
    the drift between them allows it."""
    loop_candidate_confirm_old: bool = False
    """A verified loop candidate confirms the previous one (one hypothesis) only when their
    old epochs too lie within ``loop_candidate_confirm_epochs`` of each other. Off: the
    drift between two old epochs far apart lets their loop poses agree on anything, and a
    wrong one then shares the right one's hypothesis (2D-rig world 32 at 2 cm: 908 against
    epoch 378, 20 m off, chained with the right 912-934 against epoch 0; the chi2 gate
    removes them together). See ``loop_hypothesis_ties``."""
    loop_hypothesis_ties: Literal["keep", "yield"] = "keep"
    """What a loop hypothesis that fails the likelihood-ratio test (:func:`.loop_gate.
    test_hypotheses`) is weighed against. "keep": it is removed. "yield": first the map
    matches whose plane ties it contradicts (a tie's squared whitened error rises by more
    than chi2(3) at ``loop_gate_quantile`` between the solve without the hypothesis and
    with it) are taken out, and the test is repeated: if the hypothesis then passes, the
    ties go and it stays (joint compatibility of the loop and the map: a wall tied one
    spacing off in a corridor costs the odometry nothing, the loop closure shows it), else
    it goes and the ties stay (:mod:`planodom.smoothing.loop_yield`). Off by default; see
    docs/RESULTS.md (W32TIES)."""
    loop_consistency: Literal["off", "hypotheses", "hypotheses_and_map"] = "hypotheses_and_map"
    """Batch: keep, before optimisation, the loop hypotheses of the largest set (in factors)
    that agree pairwise, PCM (:func:`.loop_gate.consistent_hypotheses`). On the 2D-rig worlds
    0, 2, .., 18 it changes no run; with ``odometry.coplanar_reextract: moved`` world 16 at
    2 cm 3.02 -> 0.019 m (18 factors aliased 4.6 m along a corridor, interleaved with 27
    right ones, all fit after optimisation: the graph tore between neighbours).
    "hypotheses_and_map": the map's accepted matches (their plane ties) are one more
    hypothesis, weighed by their ties and compared with each loop hypothesis through the
    full-rank match of least drift between them (walls seen nearest the loop's old epoch).
    Why: with ``first_epoch_refresh`` 1 on world 16 at 2 cm two hypotheses aliased 4.6 m
    along its corridor (23 factors) outnumber the right one (4), 4.62 m ATE; the map's 995
    right ties disagree with them: 0.034 m. On the ten laps (batch with loops) it changes
    no run alone (all 20 as "hypotheses"); with ``first_epoch_refresh`` 1 against this
    default: median ATE 0.0133 -> 0.0104 m at 6 mm, 0.0506 -> 0.0347 m at 2 cm, every loop
    end below 10 cm (world 18 10.5 -> 0.7 and 11.5 -> 2.0 cm), no wrong tie; worse: world 2
    0.035 -> 0.049 (6 mm) and 0.068 -> 0.098 m (2 cm), world 16 at 2 cm 0.021 -> 0.034 m,
    world 14 0.002 -> 0.003 and 0.006 -> 0.007 m. The default: it changes no lap alone and
    keeps the map's word where an aliased set outnumbers the right loop hypothesis."""
    loop_consistency_pair: Literal["nearest", "sharpest"] = "nearest"
    """The pair of factors through which ``loop_consistency`` compares two loop hypotheses:
    "nearest" the nearest in epochs (current and old), "sharpest" the one whose comparison
    has the least horizontal covariance (drift between them plus both their own). Why:
    on 2D-rig world 32 at 2 cm the nearest pair of 851-876 and 912-934 (against epochs
    0 and 1) holds a factor whose sigma along the corridor is 6.5 m, so the two agree
    although their factors of 2 cm disagree by 3.6 m. Off; see docs/RESULTS.md (W32TIES)."""
    loop_consistency_weight: Literal["factors", "revisits"] = "factors"
    """What a hypothesis weighs in ``loop_consistency``'s clique: "factors" its loop factors
    (the map its kept plane ties), "revisits" its runs of current epochs at most
    ``loop_candidate_confirm_epochs`` apart, ties broken by the factors
    (:mod:`planodom.smoothing.loop_weights`): consecutive loop poses of one pass are one
    observation of a place, and of its alias. Off; see docs/RESULTS.md (CLIQUE)."""
    loop_map_epoch: Literal["earliest", "spanning"] = "spanning"
    """``loop_consistency`` "hypotheses_and_map": the map epoch an accepted full-rank match
    places its epoch against when compared with a loop hypothesis (the old end of the
    drift between them, :func:`.loop_gate._sharpest`). "earliest": the earliest last
    sighting of its tied walls. "spanning": the last sighting by which its tied walls span
    two non-parallel normals (:func:`.match_fit.spanning_epoch`): a match tying one early
    wall and later ones is placed by the early wall along that wall's normal only, the
    rest rests on the later walls and the map's chain. Why (2D-rig world 32 at 6 mm,
    held out): the matches at epochs 766-783 tie a wall last seen at 64 and walls seen
    after 700; "earliest" compares them with the right loop hypotheses (751-787 against
    epoch 4) over the drift from 4 to 64 only, they disagree by 3 m, and the map's 1 483
    ties outvote them (ATE 3.61 m). "spanning": no match contradicts a loop hypothesis
    there, ATE 1.46 m (wrong ties kept 29 -> 3), but the clique then keeps two loop
    hypotheses aliased by a wall spacing (28 factors) over the right two (15): loop end
    3.43 -> 4.24 m. Measured on one lap of every even world 0-38, 6 mm and 2 cm (batch
    with loops): every other run unchanged to the digit (world 32 at 2 cm keeps 3.28 m:
    the right hypothesis is kept by the clique but fails the chi2 gate against the 118
    wrong ties). The default: it changes no lap but world 32 at 6 mm, better in ATE.
    """
    loop_candidate_reference: Literal["earliest", "spanning"] = "earliest"
    """``loop_verify`` "tracked": the map epoch of the accepted correction from which the
    loop candidates' bounds and their agreement with the map grow the drift to the old
    epoch (the span from it to the old epoch): "earliest" the earliest last sighting of the
    accepting match's tied walls, "spanning" the last sighting by which they span two
    non-parallel normals (as ``loop_map_epoch``): the correction rests on those later walls,
    and the drift between them and the old epoch is the prediction's. Why (2D-rig world 32
    at 2 cm, W32D): the map's correction from epoch 834 on ties a wall last seen at 30 and
    walls seen at 111-429, after the odometry lost 3.8 m at 45-107; the prediction is 4.0-4.6
    m off the truth at the lap's end, the bound from 30 0.6-2.0 m, so epoch 0 is never in
    reach and the lap makes no loop factor. Off: the wider bound lets aliases in (world 32's
    right closure is then outvoted in the clique; fresh worlds 280-298 at 2 cm: ATE ratio
    1.023, wrong loop factors kept 17 -> 18; at 6 mm 0.971); see docs/RESULTS.md (W32D)."""
    loop_map_parts: Literal["one", "corrections", "matches"] = "one"
    """``loop_consistency`` "hypotheses_and_map": the map is one node of the clique ("one"),
    or one per correction its verification took anew, with the ties up to the next
    ("corrections", :mod:`planodom.smoothing.loop_map_parts`), or per accepted full-rank
    match with the rotation-only ties up to the next ("matches"): each part is tested against
    the loop hypotheses and the other parts, so the ties after a wrong correction no longer
    outvote a right loop closure. Off; see docs/RESULTS.md (SPLIT32)."""
    loop_gate_parts: Literal["off", "corrections", "matches"] = "off"
    """A loop hypothesis that fails the chi2(5) gate is weighed against the map's parts
    whose plane ties it contradicts (split as ``loop_map_parts`` splits the clique's node):
    the graph without the hypothesis and, per such part, without the part's ties but with
    the hypothesis (eligible when the hypothesis then passes the gate) are solved, and the
    one of least robust chi2 per degree of freedom is kept (:mod:`planodom.smoothing.
    loop_gate_parts`); with ``loop_gate_removes`` "factor" the gate is as "off". Off: on
    2D-rig world 32 at 2 cm it removes a large right part on that part's own misfit (the
    plane covariances too small) and lets aliased loop hypotheses in; see docs/RESULTS.md
    (W32C)."""
    loop_gate_removes: Literal["hypothesis", "factor"] = "hypothesis"
    """The chi2(5) gate removes a failing loop factor alone or with its hypothesis. "factor":
    on the ten laps world 12 at 2 cm 0.0357 -> 0.0359 m, no other change; with ``moved``
    world 6 at 6 mm 0.108 -> 0.048 m (loop end 25 -> 3.8 cm: 10 right factors had gone);
    but over 2 000 epochs (world 0 at 6 mm, 4.8 laps) it keeps 1 449 loop factors that
    "hypothesis" removes with their hypotheses, where the map's ties close the laps
    better: ATE 0.0169 -> 0.0204 m, loop end 0.5 -> 1.5 cm, 47 -> 71 s (same machine, one
    after the other), beyond the 60 s the issue allows; hence "hypothesis"."""
    loop_factor_deskew: Literal["off", "both_epochs"] = "off"
    """Batch, with ``deskew_noise`` "none": the loop-candidate factors alone take both
    epochs' deskewing error in their covariance (:meth:`.DeskewNoise.loop_covariance`,
    the "twist_change" model of the run's own changes of motion; every other factor as
    before). Why: on continuous-motion laps a loop factor is solved from two epochs'
    planes, each deskewed with a twist off by its change of motion, an error its fit's
    covariance misses: on the fresh 2D-rig laps 320-338 25 of 26 loop factors the truth
    puts beyond 3 of their own sigmas (bar one aliased hypothesis) were within 3 sigma
    with it. No constant is new: the model is ``deskew_noise``'s. Off: on those laps the
    ATE geometric-mean ratio was 1.080 / 1.072 (6 mm / 2 cm, 7 / 4 laps), and on world
    324 the gate kept 23 loop factors it removes by default (docs/RESULTS.md, WRONGTIE)."""
    loop_gate_quantile: Fraction = 0.999
    """After optimisation, a re-identified observation whose squared whitened error exceeds
    this quantile of chi2(3) is removed and the graph solved again."""
    loop_gate_resolve_from: Literal["initial", "estimate"] = "initial"
    """Where the batch's solve after a gate round starts: the initial values ("initial": an
    estimate a wrong tie or loop hypothesis has pulled is not trusted) or the current
    estimate ("estimate": fewer steps; the removed factors' pull stays in the start).
    Measured (BATCH60): the 2 000-epoch batch with loops (world 0, 6 mm) 0.74x the CPU
    time, ATE 0.01709 -> 0.01710 m; on 2D-rig worlds 0, 2, 6, 8, 14, 18 (450 epochs, 6 mm
    and 2 cm) mixed: world 6 better (2 cm ATE 0.337 -> 0.143 m, but its loop end 1.4 ->
    5.5 cm), world 18 at 6 mm worse (ATE 0.024 -> 0.029 m, loop end 2.2 -> 3.4 cm), the
    rest within 1e-4 m. Hence "initial"."""

    def check_loop_drift(self) -> None:
        """``loop_verify_drift``, ``loop_drift_yaw`` and ``loop_refuse_ambiguous`` "run" need
        the run's drift."""
        for name in ("loop_verify_drift", "loop_drift_yaw", "loop_refuse_ambiguous"):
            if getattr(self, name) == "run" and self.loop_candidate_drift != "run":
                raise ConfigError(
                    f"smoothing.{name}: 'run' needs loop_candidate_drift 'run', "
                    f"got {self.loop_candidate_drift!r}"
                )
