"""The residual of a match at its own pose (planodom.smoothing.match_fit)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from planodom.geometry import Plane, invert_transform, transform_from_rpy_xyz
from planodom.smoothing.match_fit import (
    OffsetFit,
    ambiguity,
    epoch_ambiguity,
    offset_residuals,
    offset_verdict,
    spanning_epoch,
    tie_ambiguities,
)


def _walls() -> list[Plane]:
    """A room's walls and its floor, in the old frame (normals towards the sensor)."""
    normals = [[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]
    offsets = [3.0, 2.0, 4.0, 1.5]
    return [Plane(np.array(n), d) for n, d in zip(normals, offsets, strict=True)]


def _seen_from(T_old_curr: np.ndarray, planes: list[Plane]) -> list[Plane]:
    return [p.transformed(invert_transform(T_old_curr)) for p in planes]


def test_planes_seen_from_the_matched_pose_fit_exactly():
    T = transform_from_rpy_xyz(0.0, 0.0, 0.4, 1.2, -0.7, 0.1)
    old = _walls()
    curr = _seen_from(T, old)
    pairs = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
    fit = offset_residuals(old, curr, pairs, T, 0.02, 3.0, np.zeros((4, 4)))
    tied = fit.residuals[np.arange(4), fit.tied]
    assert np.abs(tied).max() < 1e-9
    assert np.isnan(fit.residuals[0, 1])  # opposite walls are no alternative partners
    np.testing.assert_allclose(fit.normals, [p.normal for p in old])
    np.testing.assert_allclose(fit.old_variances + fit.curr_variances, 2 * 0.02**2)
    flipped = [p.flipped() for p in curr]  # orientation does not matter
    fit = offset_residuals(old, flipped, pairs, T, 0.02, 3.0, np.zeros((4, 4)))
    assert np.abs(fit.residuals[np.arange(4), fit.tied]).max() < 1e-9


def test_a_wall_tied_to_a_parallel_wall_leaves_their_distance():
    """The current plane of wall 0 is tied to a wall parallel to it 4.9 m further: the
    residual is 4.9 m (the other pairs fit)."""
    T = transform_from_rpy_xyz(0.0, 0.0, -0.3, 0.5, 2.0, 0.0)
    old = _walls()
    curr = _seen_from(T, old)
    old.append(Plane(np.array([1.0, 0, 0]), 3.0 + 4.9))
    pairs = np.array([[4, 0], [1, 1], [2, 2], [3, 3]])
    fit = offset_residuals(old, curr, pairs, T, 0.02, 3.0, np.zeros((4, 4)))
    r = fit.residuals[np.arange(4), fit.tied]
    np.testing.assert_allclose(np.abs(r), [4.9, 0, 0, 0], atol=1e-9)
    assert abs(fit.residuals[0, 0]) < 1e-9  # its true partner, parallel: an alternative
    none = offset_residuals(old, curr, np.zeros((0, 2), int), T, 0.02, 3.0, np.zeros((0, 0)))
    assert len(none.tied) == 0


def _fit(residuals: list[float], normals: list[list[float]], between: float = 0.0) -> OffsetFit:
    """Ties m -> old plane m with the given residuals, 1 cm planes, ``between`` m^2 of map
    drift between every two of their sightings."""
    n = len(residuals)
    full = np.full((n, n), np.nan)
    full[np.arange(n), np.arange(n)] = residuals
    v = np.full(n, 0.01**2)
    cos = np.cos(np.radians(3))
    normals_ = np.array(normals, float)
    return OffsetFit(full, normals_, v, v, np.arange(n), cos, np.full((n, n), between))


def test_the_statistic_weighs_the_residual_by_the_drift_along_the_normal():
    """Closed form: a residual r along normal n under drift covariance D and plane
    variances v is chi2(1) distributed as r^2 / (n^T D n + v); drift across the normal
    does not widen the bound."""
    limit = float(chi2.ppf(0.999, 1))
    along, across = np.diag([0.5**2, 1e-6]), np.diag([1e-6, 0.5**2])
    fit = _fit([1.0], [[1.0, 0.0, 0.0]])
    assert offset_verdict(fit, along, limit) == ("", pytest.approx(1.0 / (0.25 + 2e-4)))
    assert offset_verdict(fit, across, limit)[0] == "misfit"
    empty = OffsetFit(np.zeros((0, 0)), np.zeros((0, 3)), np.zeros(0), np.zeros(0),
                      np.zeros(0, int), 1.0, np.zeros((0, 0)))  # fmt: skip
    assert offset_verdict(empty, along, limit) == ("", 0.0)


def test_parallel_ties_must_agree_whatever_the_drift():
    """Two parallel walls 2 m apart in their residuals place the pose at two places along
    their normal: a drift of 5 m lets each pass, not both; perpendicular walls are
    independent, and parallel ties a few millimetres apart agree."""
    limit = float(chi2.ppf(0.999, 1))
    drift = np.eye(2) * 5.0**2
    x, y = [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]
    assert offset_verdict(_fit([0.0, -2.0], [x, x]), drift, limit)[0] == "inconsistent ties"
    assert offset_verdict(_fit([0.0, -2.0], [x, y]), drift, limit)[0] == ""
    assert offset_verdict(_fit([0.5, 0.51], [x, x]), drift, limit)[0] == ""
    # facing walls: a shift along x moves their residuals by opposite amounts
    facing = [x, [-1.0, 0.0, 0.0]]
    assert offset_verdict(_fit([0.5, -0.5], facing), drift, limit)[0] == ""
    assert offset_verdict(_fit([0.5, 0.5], facing), drift, limit)[0] == "inconsistent ties"
    # the map's own drift between the two walls' sightings does not cancel: 1 m of it
    # explains a metre's disagreement
    assert offset_verdict(_fit([0.0, -1.0], [x, x], 1.0), drift, limit)[0] == ""


def _offsets(
    residuals: list[list[float]], normals: list[list[float]], tied: list[int]
) -> OffsetFit:
    """An offset fit of noise-free planes (variances zero) from its residuals."""
    n = len(normals)
    residual_array, normal_array = np.array(residuals, float), np.array(normals, float)
    return OffsetFit(residual_array, normal_array, np.zeros(n), np.zeros(len(tied)),
                     np.array(tied), 1.0, np.zeros((0, 0)))  # fmt: skip


def test_a_lone_tie_with_a_parallel_twin_costs_only_the_prior():
    # one wall measures x alone; its twin 1.5 m further: swapping them shifts the pose by
    # 1.5 m, which costs r^2 / (sigma_prior^2 + both offset variances) (a Gaussian's
    # marginal), nothing else
    fit = _offsets([[0.0, 1.5, np.nan]], [[1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]], [0])
    sigma, floor = 2.0, 0.05
    expected = 1.5**2 / (sigma**2 + floor**2)  # the old planes' variances are zero
    assert ambiguity(fit, sigma, floor) == pytest.approx(expected, rel=1e-9)
    assert ambiguity(fit, sigma, floor) < chi2.ppf(0.999, 1)  # the prior cannot choose
    # a tight prediction tells them apart
    assert ambiguity(fit, 0.2, floor) > chi2.ppf(0.999, 1)


def test_a_second_tie_along_the_normal_pins_the_shift():
    # two parallel walls measure x; one of them has a twin 1.5 m away: swapping it alone
    # must move the pose against the other tie: w r^2 (w + p) / (2 w + p)
    fit = _offsets([[0.0, 1.5, np.nan], [np.nan, np.nan, 0.0]],
               [[1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]], [0, 2])  # fmt: skip
    fit.residuals[1, :2] = np.nan
    sigma, floor = 2.0, 0.05
    w, p = 1.0 / floor**2, 1.0 / sigma**2
    expected = w * 1.5**2 * (w + p) / (2 * w + p)
    assert ambiguity(fit, sigma, floor) == pytest.approx(expected, rel=1e-9)
    assert ambiguity(fit, sigma, floor) > chi2.ppf(0.999, 1)


def test_a_wall_across_the_twin_leaves_it_ambiguous():
    # a perpendicular tie does not measure the shift along the twins' normal
    fit = _offsets([[0.0, 1.5, np.nan], [np.nan, np.nan, 0.0]],
               [[1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]], [0, 2])  # fmt: skip
    sigma, floor = 2.0, 0.05
    assert ambiguity(fit, sigma, floor) == pytest.approx(1.5**2 / (sigma**2 + floor**2))
    assert (
        ambiguity(_offsets([[0.0, np.nan]], [[1.0, 0, 0], [0, 1.0, 0]], [0]), 2.0, 0.05) == np.inf
    )


def test_ambiguity_from_planes_at_the_predicted_position():
    # two walls 1.5 m apart along x and a cross wall; the current epoch sees the near one
    # from a pose 0.3 m off the prediction along x
    old = [Plane(np.array([1.0, 0, 0]), 3.0), Plane(np.array([1.0, 0, 0]), 4.5),
           Plane(np.array([0, 1.0, 0]), 2.0)]  # fmt: skip
    T_true = transform_from_rpy_xyz(0.0, 0.0, 0.0, 0.3, 0.0, 0.0)
    curr = _seen_from(T_true, old[:1] + old[2:])
    fit = offset_residuals(old, curr, np.array([[0, 0], [2, 1]]), np.eye(4), 0.0, 3.0,
                           np.zeros((0, 0)))  # fmt: skip
    # at the prediction, the tie is 0.3 m off and its twin 1.5 - 0.3 = 1.2 m the other way
    np.testing.assert_allclose(fit.residuals[0, :2], [-0.3, 1.2], atol=1e-12)
    sigma, floor = 1.0, 0.01
    v = sigma**2 + floor**2  # planes without covariance, default sigma 0: the floor alone
    assert ambiguity(fit, sigma, floor) == pytest.approx((1.2**2 - 0.3**2) / v, rel=1e-9)


def test_a_twin_the_maps_drift_explains_is_the_same_wall():
    # the twin 0.3 m from the tied wall, the map drifting 0.2 m (sigma) between their
    # sightings: one wall seen twice, no competitor; 1.5 m away it competes
    sigma, floor, limit = 2.0, 0.05, float(chi2.ppf(0.999, 1))
    between = np.full((3, 3), 0.2**2)
    near = _offsets([[0.0, 0.3, np.nan]], [[1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]], [0])
    assert ambiguity(near, sigma, floor, (between, limit)) == np.inf
    assert ambiguity(near, sigma, floor) < limit  # without the map's drift it competes
    far = _offsets([[0.0, 1.5, np.nan]], [[1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]], [0])
    assert ambiguity(far, sigma, floor, (between, limit)) == ambiguity(far, sigma, floor)


def test_each_tie_has_its_own_ambiguity():
    # tie 0 has a twin within the prior, tie 1 (across) none: only tie 0 is ambiguous
    fit = _offsets([[0.0, 1.5, np.nan], [np.nan, np.nan, 0.0]],
                   [[1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]], [0, 2])  # fmt: skip
    rows = tie_ambiguities(fit, 2.0, 0.05)
    assert rows[0] == pytest.approx(1.5**2 / (2.0**2 + 0.05**2))
    assert rows[1] == np.inf


def test_a_tie_from_another_map_part_confirms_no_alias():
    # two parallel ties pin the shift along x (test above); their walls were seen in map
    # parts 2 m (sigma) apart, the twin with the first: each weighs w = 1 / (floor^2 + 4),
    # and the swap costs w r^2 (w + p) / (2 w + p), within chi2(1): ambiguous again
    fit = _offsets([[0.0, 1.5, np.nan], [np.nan, np.nan, 0.0]],
               [[1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]], [0, 2])  # fmt: skip
    fit.residuals[1, :2] = np.nan
    sigma, floor, limit = 2.0, 0.05, float(chi2.ppf(0.999, 1))
    between = np.full((3, 3), 2.0**2)  # old planes 0 and 1 (the twins) seen together
    between[:2, :2] = 0.0
    between[2, 2] = 0.0
    w, p = 1.0 / (floor**2 + 4.0), 1.0 / sigma**2
    expected = w * 1.5**2 * (w + p) / (2 * w + p)
    rows = tie_ambiguities(fit, sigma, floor, (between, limit), parts=True)
    assert rows[0] == pytest.approx(expected, rel=1e-9)
    assert rows[0] < limit
    assert tie_ambiguities(fit, sigma, floor, (between, limit))[0] > limit  # one frame
    one_part = (np.zeros((3, 3)), limit)  # seen together: the other tie pins it
    assert tie_ambiguities(fit, sigma, floor, one_part, parts=True)[0] > limit


def test_spanning_epoch_is_the_first_sighting_with_two_non_parallel_walls():
    """Walls last seen at 64 (normal x), 700 (-x, parallel), 710 (normal at 30 deg from x)
    and 705 (y), in any order: x and -x place nothing along y; with the y wall (705) they
    do. All parallel: the latest sighting. One wall: its own."""
    x, y = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    slanted = np.array([np.cos(np.radians(30)), np.sin(np.radians(30)), 0])
    normals = np.stack([slanted, -x, y, x])
    assert spanning_epoch([710, 700, 705, 64], normals) == 705
    assert spanning_epoch([710, 700, 64], normals[[0, 1, 3]]) == 710
    assert spanning_epoch([700, 64], np.stack([-x, x])) == 700
    # 5 deg apart counts as parallel at the 10 deg default, not at 3 deg
    tilted = np.array([np.cos(np.radians(5)), np.sin(np.radians(5)), 0])
    assert spanning_epoch([64, 80, 90], np.stack([x, tilted, y])) == 90
    assert spanning_epoch([64, 80, 90], np.stack([x, tilted, y]), min_angle_deg=3.0) == 80
    assert spanning_epoch([12], x[None]) == 12


LIMIT = float(chi2.ppf(0.999, 1))


def _corridor(cross: list[float]) -> list[Plane]:
    """A corridor along x seen from the origin: side walls at y = +-1.5 m, the floor, and
    walls across it at x = each of ``cross`` (m, ahead), all facing the sensor."""
    planes = [Plane(np.array([0, -1.0, 0]), 1.5), Plane(np.array([0, 1.0, 0]), 1.5),
              Plane(np.array([0, 0, 1.0]), 1.2)]  # fmt: skip
    return planes + [Plane(np.array([-1.0, 0, 0]), x) for x in cross]


def _epoch_ambiguity(old, curr, pairs, predicted_x: float, sigma: float, spacing=False):
    """:func:`epoch_ambiguity` at a prediction ``predicted_x`` m along the corridor (the
    true relative pose is the identity: the same place, revisited)."""
    T = transform_from_rpy_xyz(0.0, 0.0, 0.0, predicted_x, 0.0, 0.0)
    return epoch_ambiguity(old, curr, np.array(pairs), T, sigma, 0.02, 3.0, LIMIT, spacing)


def test_a_corridor_of_evenly_spaced_walls_leaves_the_loop_pose_ambiguous():
    # walls across the corridor every 3 m; the old epoch sees two of them, the current
    # one (the truth: the same place), and the prediction is 2 m off along the corridor
    # (sigma 3 m): tied to the farther wall the pose is 3 m off, tied to the nearer it is
    # right, and the prediction cannot tell which
    old, curr = _corridor([4.0, 7.0]), _corridor([4.0])
    T_true = np.eye(4)
    assert curr[3].transformed(T_true).offset == pytest.approx(old[3].offset)  # the truth
    aliased = [[0, 0], [1, 1], [2, 2], [4, 3]]  # the current cross wall tied to x = 7
    right = [[0, 0], [1, 1], [2, 2], [3, 3]]
    for pairs in (aliased, right):  # either way, the other one competes
        assert _epoch_ambiguity(old, curr, pairs, -2.0, 3.0) <= LIMIT
    # a prediction sharp to a fraction of the spacing tells them apart (0.3 m off)
    assert _epoch_ambiguity(old, curr, right, 0.3, 0.3) > LIMIT


def test_a_corridor_with_one_end_wall_gives_an_unambiguous_loop_pose():
    # the same corridor closed by one end wall: the match's position along it is the end
    # wall's, with no parallel wall to confuse it with in either epoch (the floor tells
    # nothing along x: a level plane is left out)
    old, curr = _corridor([4.0]), _corridor([4.0])
    pairs = [[0, 0], [1, 1], [2, 2], [3, 3]]
    assert _epoch_ambiguity(old, curr, pairs, -2.0, 3.0) == np.inf
    assert _epoch_ambiguity(old, curr, pairs, -2.0, 3.0, spacing=True) == np.inf


def test_the_current_epochs_second_wall_is_a_competitor_too():
    # the old epoch sees one cross wall, the current two: the old planes alone show no
    # alternative (world 32's case), the current epoch's do
    old, curr = _corridor([4.0]), _corridor([4.0, 7.0])
    aliased = [[0, 0], [1, 1], [2, 2], [3, 4]]  # the current wall at x = 7 tied to x = 4
    T = transform_from_rpy_xyz(0.0, 0.0, 0.0, -2.0, 0.0, 0.0)
    only_old = offset_residuals(old, curr, np.array(aliased), T, 0.02, 3.0, np.zeros((0, 0)))
    assert ambiguity(only_old, 3.0, 0.02) == np.inf
    assert _epoch_ambiguity(old, curr, aliased, -2.0, 3.0) <= LIMIT


def test_a_wall_extracted_twice_is_no_competitor():
    # the old epoch holds the end wall twice, 5 mm apart (two segments of one wall)
    old, curr = _corridor([4.0, 4.005]), _corridor([4.0])
    pairs = [[0, 0], [1, 1], [2, 2], [3, 3]]
    assert _epoch_ambiguity(old, curr, pairs, -2.0, 3.0) == np.inf


def test_spacing_tries_the_wall_beyond_that_no_epoch_shows():
    # walls across every 3 m at x = 1, 4, 7; the old epoch sees 4 and 7, the current
    # (truly at the same place) only the one at 1 (the others hidden): tied to 4, the
    # pose 3 m off; the prediction halfway (1.5 m off, sigma 1 m) fits the right wall
    # (x = 1, unseen by the old epoch) as well as the tied one, the wall at 7 far worse:
    # only "spacing" (the 3 m the other way) finds the competitor
    old = _corridor([4.0, 7.0])
    curr = _corridor([1.0])
    aliased = [[0, 0], [1, 1], [2, 2], [3, 3]]
    assert _epoch_ambiguity(old, curr, aliased, 1.5, 1.0) > LIMIT
    assert _epoch_ambiguity(old, curr, aliased, 1.5, 1.0, spacing=True) == pytest.approx(0.0)


def _row_of_walls(predicted_x: float, tied: int) -> OffsetFit:
    """A row of parallel walls across x at 2.0, 5.1 and 8.2 m (3.1 m apart) and a wall
    along it (normal y); the current epoch, truly at the map's origin, sees the first wall
    and the wall along the row; the prediction is ``predicted_x`` m off along the row, and
    the wall the current epoch sees is tied to row wall ``tied`` (the wall along the row to
    its own). Offsets at the predicted position (:func:`tie_ambiguities`)."""
    old = [Plane(np.array([1.0, 0, 0]), x) for x in (2.0, 5.1, 8.2)]
    old.append(Plane(np.array([0, 1.0, 0]), 1.5))
    curr = _seen_from(np.eye(4), [old[0], old[3]])
    T_pred = transform_from_rpy_xyz(0.0, 0.0, 0.0, predicted_x, 0.0, 0.0)
    pairs = np.array([[tied, 0], [3, 1]])
    return offset_residuals(old, curr, pairs, T_pred, 0.0, 3.0, np.zeros((0, 0)))


def test_a_row_wall_tied_a_spacing_off_is_refused_under_an_honest_prior():
    """loop_refuse_ambiguous "run": the prediction one spacing off along the row, so the
    seen wall fits its neighbour exactly and is tied to it; the run's drift says the
    prediction is good to 1.5 m (sigma): the right wall, 3.1 m away (2 sigma), competes
    and the tie is refused. The wall along the row says nothing along it (the shift is
    the prior's alone: closed form). Under the map's drift between the row walls'
    sightings (3 m sigma) the old "same wall" exclusion drops the competitor (the two
    walls a spacing apart look like one wall seen twice) and the alias passes."""
    fit = _row_of_walls(-3.1, tied=1)
    np.testing.assert_allclose(fit.residuals[0, :3], [-3.1, 0.0, 3.1], atol=1e-12)
    sigma, floor = 1.5, 0.05
    between = np.full((4, 4), 3.0**2)
    np.fill_diagonal(between, 0.0)
    # "run": the map's drift for "parts" only, no "same wall" exclusion (its quantile 0)
    rows = tie_ambiguities(fit, sigma, floor, (between, 0.0), parts=True)
    # nothing else places the pose along x: the swap costs the prior's and the tie's own
    # variance (the floor, and the drift to the other tie's map part: parts)
    v = sigma**2 + floor**2 + 3.0**2
    assert rows[0] == pytest.approx(3.1**2 / v, rel=1e-9)
    assert rows[0] <= LIMIT  # refused
    assert rows[1] == np.inf  # the wall along the row has no parallel competitor
    assert tie_ambiguities(fit, sigma, floor, (between, LIMIT))[0] == np.inf  # "same wall"


def test_a_well_predicted_tie_in_the_row_is_kept():
    """The same row, the prediction 0.1 m off after an accepted correction (the run's drift
    since then at the bounds' floor, 0.17 m): tied to the right wall, its neighbours 3.1
    and 6.2 m away cost far more than chi2(1) at 0.999: the tie is kept."""
    fit = _row_of_walls(0.1, tied=0)
    rows = tie_ambiguities(fit, 0.17, 0.05, (np.zeros((4, 4)), 0.0), parts=True)
    assert rows[0] > LIMIT
    assert rows[0] == pytest.approx((3.2**2 - 0.1**2) / (0.17**2 + 0.05**2), rel=1e-9)
