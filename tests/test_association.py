"""LDA and SDA: vectorised vs brute force, absolute constraints, injectivity, truth."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from planes_factory import noisy, observe, random_motion, world_planes

from planodom.association import (
    lenient_association,
    strict_association,
)
from planodom.config import AssociationConfig
from planodom.geometry import Plane, transform_from_rpy_xyz
from planodom.planes import PlaneSet

LOOSE = AssociationConfig(
    max_translation_m=1e3, max_rotation_deg=180.0, overlap_margin_m=1e3, offset_tol_m=1e3
)


def lda_of(prev, curr, *args, **kwargs):
    """LDA of two plane lists."""
    return lenient_association(
        PlaneSet.from_planes(prev), PlaneSet.from_planes(curr), *args, **kwargs
    )


def sda_of(prev, curr, *args, **kwargs):
    """SDA of two plane lists."""
    return strict_association(
        PlaneSet.from_planes(prev), PlaneSet.from_planes(curr), *args, **kwargs
    )


def dihedral_angle(n1: np.ndarray, n2: np.ndarray) -> float:
    """Angle (rad, in [0, pi]) between two normals, by atan2 of |n1 x n2| and n1 . n2: the
    brute-force reference for the arccos of the vectorised association."""
    return float(np.arctan2(np.linalg.norm(np.cross(n1, n2)), np.dot(n1, n2)))


def two_epochs(seed: int, n_walls: int = 6, motion=None):
    rng = np.random.default_rng(seed)
    world = world_planes(rng, n_walls)
    T_w_a = transform_from_rpy_xyz(0.02, -0.01, rng.uniform(-3, 3), 1.0, 2.0, 0.0)
    T_ab = random_motion(rng) if motion is None else motion
    return world, observe(world, T_w_a), observe(world, T_w_a @ T_ab), T_ab


def true_pairs(prev: list[Plane], curr: list[Plane], parallel_deg: float) -> set:
    """Pair associations that are correct by truth id, both orders as seen."""
    j_of = {p.truth_id: j for j, p in enumerate(curr)}
    out = set()
    for i1, i2 in itertools.combinations(range(len(prev)), 2):
        a = dihedral_angle(prev[i1].normal, prev[i2].normal)
        if np.radians(parallel_deg) <= a <= np.pi - np.radians(parallel_deg):
            out.add((i1, i2, j_of[prev[i1].truth_id], j_of[prev[i2].truth_id]))
    return out


def as_set(lda) -> set:
    return {
        tuple(int(v) for v in np.r_[p, c])
        for p, c in zip(lda.prev_pairs, lda.curr_pairs, strict=True)
    }


def brute_force_lda(prev, curr, parallel_deg, tol_deg) -> set:
    """Relative constraint only, with loops: all pairs whose dihedral angles agree."""
    par, tol = np.radians(parallel_deg), np.radians(tol_deg)
    out = set()
    for i1, i2 in itertools.combinations(range(len(prev)), 2):
        a = dihedral_angle(prev[i1].normal, prev[i2].normal)
        if not par <= a <= np.pi - par:
            continue
        for j1, j2 in itertools.permutations(range(len(curr)), 2):
            b = dihedral_angle(curr[j1].normal, curr[j2].normal)
            if par <= b <= np.pi - par and abs(a - b) <= tol:
                out.add((i1, i2, j1, j2))
    return out


@given(st.integers(0, 10_000))
def test_lda_relative_constraint_matches_brute_force(seed):
    _, prev, curr, _ = two_epochs(seed)
    lda = lda_of(prev, curr, LOOSE)
    assert as_set(lda) == brute_force_lda(
        prev, curr, LOOSE.parallel_angle_deg, LOOSE.dihedral_tol_deg
    )


@given(st.integers(0, 10_000))
def test_lda_keeps_every_true_pair_within_the_motion_bounds(seed):
    _, prev, curr, _ = two_epochs(seed)
    lda = lda_of(prev, curr)
    found = as_set(lda)
    assert true_pairs(prev, curr, 15.0) <= found
    # The rotations of the true pairs are the true rotation.
    assert len(found) >= len(true_pairs(prev, curr, 15.0))


def test_absolute_constraints_prune_the_ambiguous_pairs():
    loose = total = 0
    for seed in range(20):
        _, prev, curr, _ = two_epochs(seed, n_walls=8)
        loose += len(lda_of(prev, curr, LOOSE))
        total += len(lda_of(prev, curr))
    assert total < 0.5 * loose


def test_motion_beyond_the_bounds_needs_a_prior_or_larger_bounds():
    big = transform_from_rpy_xyz(0.01, 0.0, np.radians(40.0), 3.0, -1.0)
    _, prev, curr, T = two_epochs(7, motion=big)
    want = true_pairs(prev, curr, 15.0)
    assert not want & as_set(lda_of(prev, curr))  # default: 20 deg, 1 m
    assert want <= as_set(lda_of(prev, curr, prior=T))
    wide = AssociationConfig(max_rotation_deg=60.0, max_translation_m=4.0)
    assert want <= as_set(lda_of(prev, curr, wide))


def test_rotations_of_true_pairs_are_exact():
    _, prev, curr, T = two_epochs(3)
    lda = lda_of(prev, curr)
    want = true_pairs(prev, curr, 15.0)
    assert want
    for p, c, R in zip(lda.prev_pairs, lda.curr_pairs, lda.rotations, strict=True):
        if (p[0], p[1], c[0], c[1]) in want:
            np.testing.assert_allclose(R, T[:3, :3], atol=1e-12)
            np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
            assert np.linalg.det(R) > 0


def test_lda_of_degenerate_inputs_is_empty():
    n = np.array([1.0, 0.0, 0.0])
    parallel = [Plane(n, 2.0), Plane(n, 5.0), Plane(-n, 3.0)]
    assert len(lda_of(parallel, parallel)) == 0
    assert len(lda_of(parallel[:1], parallel[:1])) == 0
    assert len(lda_of([], [])) == 0
    assert lda_of([], []).plane_associations().shape == (0, 2)


def test_plane_associations_are_unique_and_sorted():
    _, prev, curr, _ = two_epochs(5)
    lda = lda_of(prev, curr)
    ij = lda.plane_associations()
    assert len(np.unique(ij, axis=0)) == len(ij)
    assert np.all(np.diff(ij[:, 0] * 1000 + ij[:, 1]) > 0)
    pp, cp = lda.prev_pairs, lda.curr_pairs  # every plane of every pair, nothing else

    def distinct(p: np.ndarray, c: np.ndarray) -> list[tuple[int, int]]:
        return sorted(
            {(int(a), int(b)) for k in (0, 1) for a, b in zip(p[:, k], c[:, k], strict=False)}
        )

    assert [tuple(r) for r in ij.tolist()] == distinct(pp, cp) and ij.dtype == np.intp
    some = np.arange(len(lda)) % 2 == 0
    sub = lda.plane_associations(some).tolist()
    assert [tuple(r) for r in sub] == distinct(pp[some], cp[some])


# ----------------------------------------------------------------------------- SDA


@given(st.integers(0, 10_000))
def test_sda_recovers_truth_and_is_injective(seed):
    _, prev, curr, T = two_epochs(seed)
    ij = sda_of(prev, curr, T[:3, :3])
    assert len(np.unique(ij[:, 0])) == len(ij) == len(np.unique(ij[:, 1]))
    truth = {
        (i, j) for i, p in enumerate(prev) for j, q in enumerate(curr) if p.truth_id == q.truth_id
    }
    assert {tuple(r) for r in ij.tolist()} == truth


def test_sda_stays_injective_with_duplicated_planes():
    rng = np.random.default_rng(2)
    _, prev, curr, T = two_epochs(2)
    # Near-copies of every current plane (5 mm and 0.2 deg away) compete for each match.
    curr2 = curr + noisy(curr, rng, np.radians(0.2), 0.005)
    ij = sda_of(prev, curr2, T[:3, :3], translation=T[:3, 3], translation_bound=0.05)
    assert len(np.unique(ij[:, 0])) == len(ij) == len(np.unique(ij[:, 1]))
    assert len(ij) == len(prev)
    assert all(prev[i].truth_id == curr2[j].truth_id for i, j in ij)


def test_sda_rejects_a_wrong_rotation():
    _, prev, curr, T = two_epochs(4)
    wrong = transform_from_rpy_xyz(0, 0, np.radians(10.0), 0, 0)[:3, :3] @ T[:3, :3]
    ij = sda_of(prev, curr, wrong)
    # Only planes whose normals are (nearly) vertical survive a 10 deg yaw error.
    assert all(abs(prev[i].normal[2]) > 0.9 for i, _ in ij)


@given(st.integers(0, 7), st.integers(0, 7), st.integers(0, 2**31 - 1))
def test_sda_kept_pairs_are_numpys_column_stack(kp, kc, seed):
    """SDA's compiled selection of the gated assignment pairs equals the numpy form it
    replaced, values, dtype and layout."""
    from scipy.optimize import linear_sum_assignment

    from planodom.association import _kept_pairs

    rng = np.random.default_rng(seed)
    ok = rng.random((kp, kc)) < 0.5
    rows, cols = linear_sum_assignment(rng.random((kp, kc)))
    keep = ok[rows, cols]
    want = np.column_stack([rows[keep], cols[keep]]).astype(np.intp)
    got = _kept_pairs(ok, rows, cols)
    assert got.dtype == want.dtype and got.shape == want.shape and got.flags.c_contiguous
    np.testing.assert_array_equal(got, want)


def test_tilt_bound_drops_tilted_candidates_and_keeps_a_large_yaw():
    """``max_tilt_deg``: every kept candidate rotation tilts the base z axis by at most the
    bound plus the normal tolerance (checked on its own matrix), whatever the rotation
    bound; a 90 deg yaw with 3 deg of tilt keeps its true pairs, a 40 deg roll loses them."""
    tilted = AssociationConfig(max_translation_m=1e3, max_rotation_deg=180.0, max_tilt_deg=20.0,
                               overlap_margin_m=1e3, offset_tol_m=1e3)  # fmt: skip
    limit = np.cos(np.radians(20.0 + tilted.normal_tol_deg))
    yawed = transform_from_rpy_xyz(0.05, 0.0, np.pi / 2, 0.5, 0.2)
    rolled = transform_from_rpy_xyz(np.radians(40.0), 0.0, 0.3, 0.5, 0.2)
    for motion, kept in ((yawed, True), (rolled, False)):
        _, prev, curr, _ = two_epochs(5, n_walls=8, motion=motion)
        want = true_pairs(prev, curr, 15.0)
        assert want and want <= as_set(lda_of(prev, curr, LOOSE))  # without the tilt bound
        lda = lda_of(prev, curr, tilted)
        assert all(R[2, 2] >= limit for R in lda.rotations)
        assert (want <= as_set(lda)) is kept
        if not kept:
            assert not want & as_set(lda)
