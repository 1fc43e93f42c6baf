"""The least-squares refinement over all associated planes (planodom.odometry.refine)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, PlaneSupport, transform_from_rpy_xyz
from planodom.odometry import Status, estimate_relative_pose
from planodom.odometry.refine import plane_rotation, plane_translation
from planodom.planes import PlaneSet
from tests.planes_factory import observe, square_polygon
from tests.pose_checks import pose_error

#: A fitted plane's (n, d) covariance: 0.01 deg, 1 mm (a wall of ~100 points at 6 mm).
_COV = np.diag([np.radians(0.01) ** 2] * 3 + [0.001**2])


def _wall(yaw: float, dist: float, along: float = 0.0, truth_id: int = 0) -> Plane:
    """A vertical wall whose normal has azimuth ``yaw`` + 180 deg (it faces the origin from
    ``dist`` m away), support around ``along`` m to the side."""
    n = -np.array([np.cos(yaw), np.sin(yaw), 0.0])
    c = -dist * n + along * np.array([-n[1], n[0], 0.0]) + [0.0, 0.0, 1.0]
    return Plane(n, float(-n @ c), covariance=_COV, truth_id=truth_id,
                 support=PlaneSupport(c, square_polygon(c, n, 3.0), 100))  # fmt: skip


def _ground(truth_id: int) -> Plane:
    c = np.array([0.0, 0.0, -1.5])
    n = np.array([0.0, 0.0, 1.0])
    return Plane(n, 1.5, covariance=_COV, truth_id=truth_id,
                 support=PlaneSupport(c, square_polygon(c, n, 8.0), 500))  # fmt: skip


def _epochs(world: list[Plane], T_true: np.ndarray, yaw0: float = 0.3):
    T_w_a = transform_from_rpy_xyz(0.01, -0.02, yaw0, 1.0, -2.0, 0.3)
    return observe(world, T_w_a), observe(world, T_w_a @ T_true)


def _motion(rng: np.random.Generator) -> np.ndarray:
    r = np.radians(rng.uniform(-2, 2, 3)) * [0.3, 0.3, 1.0]
    return transform_from_rpy_xyz(*r, *rng.uniform(-0.5, 0.5, 2), 0.0)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 100_000), st.floats(10.0, 19.0))
def test_walls_a_few_degrees_apart_measure_the_translation(seed, apart_deg):
    """Ground and two walls ``apart_deg`` apart in yaw (a non-Manhattan block): no pair
    cuts at the paper's 20 deg, yet together they fix the horizontal translation."""
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(-np.pi, np.pi)
    world = [_wall(yaw, 8.0, 0.0, 0), _wall(yaw + np.radians(apart_deg), 14.0, 2.0, 1),
             _ground(2)]  # fmt: skip
    T_true = _motion(rng)
    prev, curr = _epochs(world, T_true)
    r = estimate_relative_pose(prev, curr, PlanodomConfig())
    assert r.status is Status.OK
    np.testing.assert_allclose(r.T_prev_curr, T_true, atol=1e-8)
    # The paper's single consensus candidate cannot: every pair is too narrow.
    old = PlanodomConfig().updated({"odometry.refinement": "none"})
    assert estimate_relative_pose(prev, curr, old).status is Status.DEGENERATE


def test_a_corridor_measures_its_cross_track_offset_only():
    """Two parallel walls and the ground: degenerate, yet the offset across the walls is
    measured exactly while the along-track part stays at the prior."""
    rng = np.random.default_rng(3)
    world = [_wall(0.0, 3.0, 0.0, 0), _wall(np.pi, 4.0, 1.0, 1), _ground(2)]
    T_true = _motion(rng)
    prev, curr = _epochs(world, T_true, yaw0=0.0)
    prior = T_true.copy()
    prior[:2, 3] += [0.05, 0.04]  # off in both directions
    r = estimate_relative_pose(prev, curr, PlanodomConfig(), prior=prior)
    assert r.status is Status.DEGENERATE
    # The walls' normal in the previous frame: the cross-track direction.
    across = prev[0].normal[:2] / np.linalg.norm(prev[0].normal[:2])
    along = np.array([-across[1], across[0]])
    t, t_true, t_prior = r.T_prev_curr[:2, 3], T_true[:2, 3], prior[:2, 3]
    # Up to the prior's pull: its information (1 / 0.3 m squared) against the walls'.
    assert abs((t - t_true) @ across) < 1e-4
    assert abs((t - t_prior) @ along) < 1e-3


def _noisy(planes: list[Plane], rng: np.random.Generator, sigma_d: float) -> PlaneSet:
    """The planes with offset noise ``sigma_d`` (m) and that as their covariance."""
    cov = np.diag([0.0, 0.0, 0.0, sigma_d**2])
    noisy = [Plane(p.normal, p.offset + rng.normal(0.0, sigma_d), covariance=cov,
                   support=p.support) for p in planes]  # fmt: skip
    return PlaneSet.from_planes(noisy)


def test_translation_covariance_matches_its_scatter():
    """Offset noise only: the estimates scatter as the reported covariance says (mean
    normalised squared error near 2 for two dimensions), and 10 deg walls are measured."""
    rng = np.random.default_rng(7)
    world = [_wall(0.2, 6.0, 0.0, 0), _wall(0.2 + np.radians(10.0), 9.0, 1.0, 1), _ground(2)]
    T_true = transform_from_rpy_xyz(0.0, 0.0, 0.0, 0.4, 0.1, 0.0)
    prev, curr = _epochs(world, T_true, yaw0=0.0)
    ij = np.array([[0, 0], [1, 1], [2, 2]])
    sigma = 0.002
    nees = []
    for _ in range(400):
        p, c = _noisy(prev, rng, sigma), _noisy(curr, rng, sigma)
        fit = plane_translation(p, c, T_true[:3, :3], ij, np.zeros(3), 0.9, 1e-6, 0.05, 1e4)
        assert fit.measured and fit.z_observed
        e = fit.t[:2] - T_true[:2, 3]
        nees.append(e @ np.linalg.solve(fit.cov_xy, e))
    assert 1.7 < np.mean(nees) < 2.3


def test_procrustes_rotation_is_exact_on_noise_free_planes():
    rng = np.random.default_rng(11)
    world = [_wall(0.1, 6.0, 0.0, 0), _wall(1.4, 9.0, 1.0, 1), _wall(2.9, 7.0, 0.0, 2),
             _ground(3)]  # fmt: skip
    T_true = _motion(rng)
    prev, curr = _epochs(world, T_true)
    ij = np.column_stack([np.arange(4), np.arange(4)])
    R = plane_rotation(PlaneSet.from_planes(prev), PlaneSet.from_planes(curr), np.eye(3), ij,
                       1e-3, np.radians(15.0))  # fmt: skip
    assert pose_error(np.block([[R, np.zeros((3, 1))], [np.zeros((1, 3)), 1.0]]),
                      np.block([[T_true[:3, :3], np.zeros((3, 1))],
                                [np.zeros((1, 3)), 1.0]]))[0] < 1e-10  # fmt: skip


@pytest.mark.parametrize("refinement", ["translation", "pose"])
def test_refinement_keeps_exact_recovery_in_a_random_scene(refinement):
    rng = np.random.default_rng(5)
    world = [_wall(a, d, 0.0, k) for k, (a, d) in enumerate([(0.0, 5.0), (1.6, 7.0),
             (3.0, 9.0), (4.5, 6.0)])] + [_ground(4)]  # fmt: skip
    T_true = _motion(rng)
    prev, curr = _epochs(world, T_true)
    cfg = PlanodomConfig().updated({"odometry.refinement": refinement})
    r = estimate_relative_pose(prev, curr, cfg)
    assert r.status is Status.OK
    np.testing.assert_allclose(r.T_prev_curr, T_true, atol=1e-8)


@pytest.mark.parametrize("shift_m", [0.05, -0.3])
def test_an_association_to_a_coplanar_neighbour_does_not_move_the_translation(shift_m):
    """Noise-free ground and four walls, one of them associated with a parallel plane
    ``shift_m`` behind it (a neighbouring facade, or a fit across two surfaces): the
    translation stays exact (the association is dropped as an outlier)."""
    world = [_wall(0.1, 6.0, 0.0, 0), _wall(0.1 + np.radians(35.0), 9.0, 1.0, 1),
             _wall(0.1 + np.radians(95.0), 7.0, -1.0, 2),
             _wall(0.1 + np.radians(200.0), 11.0, 0.5, 3), _ground(4)]  # fmt: skip
    T_true = transform_from_rpy_xyz(0.004, -0.003, 0.02, 0.45, -0.12, 0.01)
    prev, curr = _epochs(world, T_true)
    planes = [Plane(p.normal, p.offset + (shift_m if k == 1 else 0.0), covariance=_COV,
                    support=p.support) for k, p in enumerate(curr)]  # fmt: skip
    ij = np.array([[k, k] for k in range(5)])
    p, c = PlaneSet.from_planes(prev), PlaneSet.from_planes(planes)
    fit = plane_translation(p, c, T_true[:3, :3], ij, np.zeros(3), 0.9, 0.003, 0.03, 1.0)
    assert fit.measured and fit.n_planes == 4
    np.testing.assert_allclose(fit.t, T_true[:3, 3], atol=1e-9)


def _tilted(normal: np.ndarray, point: np.ndarray, truth_id: int) -> Plane:
    n = normal / np.linalg.norm(normal)
    return Plane(n, float(-n @ point), covariance=_COV, truth_id=truth_id,
                 support=PlaneSupport(point, square_polygon(point, n, 8.0), 500))  # fmt: skip


def _corridor(bias_m: float):
    """A corridor along x (walls at y = +-1.5 m), a level floor and a ceiling sloping
    2 deg along x (its normal's x part measures x only to ~9 cm with 3 mm offsets): the
    ceiling of the current epoch is ``bias_m`` off. Returns (prev, curr, T_true)."""
    world = [_wall(np.pi / 2, 1.5, 0.0, 0), _wall(-np.pi / 2, 1.5, 0.0, 1), _ground(2),
             _tilted(np.array([np.sin(np.radians(2.0)), 0.0, -1.0]),
                     np.array([0.0, 0.0, 1.5]), 3)]  # fmt: skip
    T_true = transform_from_rpy_xyz(0.0, 0.0, 0.0, 0.4, 0.03, 0.01)
    T_w_a = np.eye(4)
    prev, curr = observe(world, T_w_a), observe(world, T_w_a @ T_true)
    curr[3] = Plane(curr[3].normal, curr[3].offset + bias_m, covariance=_COV,
                    support=curr[3].support)  # fmt: skip
    return PlaneSet.from_planes(prev), PlaneSet.from_planes(curr), T_true


@pytest.mark.parametrize("bias_m", [0.0, 0.003])
def test_kept_holds_the_unmeasured_direction_and_solves_the_others(bias_m):
    """keep_weak: along the corridor x stays at t0 exactly whatever the sloping ceiling
    says, y (the walls) is exact; without it the ceiling's 3 mm bias moves x by
    centimetres (about bias / sin 2 deg, shrunk by the prior)."""
    p, c, T_true = _corridor(bias_m)
    ij = np.array([[k, k] for k in range(4)])
    t0 = np.array([0.3, 0.0, 0.0])
    kept = plane_translation(p, c, np.eye(3), ij, t0, 0.9, 0.003, 0.03, 0.09, unmeasured="kept")
    assert not kept.measured and kept.z_observed
    assert kept.t[0] == t0[0]
    assert abs(kept.t[1] - T_true[1, 3]) < 1e-9
    assert abs(kept.t[2] - T_true[2, 3]) < 0.002 + bias_m  # the ceiling's share of z
    blended = plane_translation(p, c, np.eye(3), ij, t0, 0.9, 0.003, 0.03, 0.09)
    assert not blended.measured
    if bias_m == 0.0:  # noise-free, the weak information is right: x moves to the truth
        assert abs(blended.t[0] - T_true[0, 3]) < abs(t0[0] - T_true[0, 3])
    else:  # 3 mm on the ceiling move x by more than it (the prior's share aside)
        exact = plane_translation(*_corridor(0.0)[:2], np.eye(3), ij, t0, 0.9, 0.003, 0.03,
                                  0.09)  # fmt: skip
        assert abs(blended.t[0] - exact.t[0]) > 0.02


def test_kept_changes_nothing_when_every_direction_is_measured():
    rng = np.random.default_rng(3)
    world = [_wall(0.2, 6.0, 0.0, 0), _wall(1.5, 9.0, 1.0, 1), _ground(2)]
    T_true = transform_from_rpy_xyz(0.0, 0.0, 0.0, 0.4, 0.1, 0.0)
    prev, curr = _epochs(world, T_true, yaw0=0.0)
    p, c = _noisy(prev, rng, 0.002), _noisy(curr, rng, 0.002)
    ij = np.array([[0, 0], [1, 1], [2, 2]])
    a = plane_translation(p, c, T_true[:3, :3], ij, np.zeros(3), 0.9, 0.003, 0.03, 0.09)
    b = plane_translation(p, c, T_true[:3, :3], ij, np.zeros(3), 0.9, 0.003, 0.03, 0.09,
                          unmeasured="kept")  # fmt: skip
    assert a.measured and b.measured
    np.testing.assert_array_equal(a.t, b.t)


def test_a_degenerate_epoch_keeps_the_prediction_along_the_corridor():
    """Through the solver with ``odometry.refine_unmeasured: kept``: the corridor epoch is
    degenerate and its x is the prior's."""
    p, c, T_true = _corridor(0.003)
    prior = transform_from_rpy_xyz(0.0, 0.0, 0.0, 0.3, 0.0, 0.0)
    cfg = PlanodomConfig().updated({"odometry.refine_unmeasured": "kept"})
    r = estimate_relative_pose(p, c, cfg, prior)
    assert r.status is Status.DEGENERATE
    assert abs(r.T_prev_curr[0, 3] - 0.3) < 1e-12
    assert abs(r.T_prev_curr[1, 3] - T_true[1, 3]) < 1e-6


def test_walls_takes_x_from_the_walls_not_the_sloping_ceiling():
    """``unmeasured="walls"``: a wall 5 deg off the corridor's axis measures x weakly
    (noise-free: x moves from t0 towards the truth); the ceiling's 3 mm bias leaves x, y
    unchanged, where it moves the default's x by more than twice the bias."""
    ij = np.array([[k, k] for k in range(5)])
    t0 = np.array([0.3, 0.0, 0.0])
    fits = {}
    for bias in (0.0, 0.003):
        p, c, T_true = _corridor(bias)
        extra = _wall(np.pi / 2 + np.radians(5.0), 2.5, 4.0, 4)
        pe, ce = observe([extra], np.eye(4)), observe([extra], T_true)
        p = PlaneSet.from_planes([*_planes_of(p), *pe])
        c = PlaneSet.from_planes([*_planes_of(c), *ce])
        for mode in ("prior", "walls"):
            fits[mode, bias] = plane_translation(p, c, np.eye(3), ij, t0, 0.9, 0.003, 0.03,
                                                 0.09, unmeasured=mode)  # fmt: skip
    walls = fits["walls", 0.0]
    assert not walls.measured
    assert 0.0 < walls.t[0] - t0[0] < T_true[0, 3] - t0[0]
    assert abs(walls.t[1] - T_true[1, 3]) < 1e-3
    np.testing.assert_allclose(fits["walls", 0.003].t[:2], walls.t[:2], atol=1e-12)
    assert abs(fits["prior", 0.003].t[0] - fits["prior", 0.0].t[0]) > 2 * 0.003


def _planes_of(s: PlaneSet) -> list[Plane]:
    return [Plane(s.normals[k], float(s.offsets[k]), covariance=_COV) for k in range(len(s))]


def _ground_and_wall(far_bias_m: float | None = None):
    """The 2D rig's degenerate epoch: the ground and one wall (normal azimuth 0.4 rad +
    180 deg); with ``far_bias_m``, a far wall 33 deg from it whose offsets have a 3 cm
    sigma, the current one that far off. Returns (prev, curr, T_true, along) with
    ``along`` (2,) the along-wall unit vector."""
    world = [_ground(0), _wall(0.4, 8.0, 0.0, 1)]
    if far_bias_m is not None:
        far = _wall(0.4 + np.radians(147.0), 40.0, 0.0, 2)
        world.append(Plane(far.normal, far.offset, covariance=np.diag([1e-8] * 3 + [0.03**2]),
                           support=far.support))  # fmt: skip
    T_true = transform_from_rpy_xyz(0.0, 0.0, 0.01, 0.113, 0.02, 0.004)
    prev, curr = observe(world, np.eye(4)), observe(world, T_true)
    if far_bias_m is not None:
        curr[2] = Plane(curr[2].normal, curr[2].offset + far_bias_m,
                        covariance=curr[2].covariance, support=curr[2].support)  # fmt: skip
    along = np.array([-np.sin(0.4), np.cos(0.4)])
    return PlaneSet.from_planes(prev), PlaneSet.from_planes(curr), T_true, along


def test_prediction_keeps_the_along_wall_step_and_measures_the_others():
    """Ground and one wall: the along-wall step is the prediction's exactly, with the
    prediction's variance; across the wall and z the truth's (noise-free planes); "prior"
    keeps the consensus's value there instead."""
    p, c, T_true, along = _ground_and_wall()
    ij = np.array([[0, 0], [1, 1]])
    t_true = T_true[:3, 3]
    t0 = t_true + np.r_[0.10 * along, 0.0]  # the consensus's (an unmeasured value)
    pred = t_true + np.r_[-0.07 * along, 0.0]
    R = T_true[:3, :3]
    fit = plane_translation(p, c, R, ij, t0, 0.9, 0.003, 0.03, 0.09, unmeasured="prediction",
                            prediction_var=0.02**2, predicted=pred)  # fmt: skip
    assert not fit.measured and fit.z_observed
    assert abs(fit.t[:2] @ along - pred[:2] @ along) < 1e-12
    normal = np.array([along[1], -along[0]])
    assert abs(fit.t[:2] @ normal - t_true[:2] @ normal) < 1e-6
    assert abs(fit.t[2] - t_true[2]) < 1e-6
    assert along @ fit.cov_xy @ along == pytest.approx(0.02**2, rel=1e-3)
    prior = plane_translation(p, c, R, ij, t0, 0.9, 0.003, 0.03, 0.09)
    assert abs(prior.t[:2] @ along - t0[:2] @ along) < 1e-6
    none = plane_translation(p, c, R, ij, t0, 0.9, 0.003, 0.03, 0.09, unmeasured="prediction")
    np.testing.assert_array_equal(none.t, prior.t)  # no prediction: "prior"


@pytest.mark.parametrize("bias_m", [0.0, 0.05])
def test_a_weak_far_wall_does_not_move_the_kept_direction(bias_m):
    """A far wall measuring the along-wall direction to ~0.1 m (less than a 2 cm
    prediction): "prediction" keeps the prediction's along-wall step whatever its offset
    says; "prior" (the motion bound's 0.3 m) follows the far wall's 5 cm bias by more."""
    p, c, T_true, along = _ground_and_wall(bias_m)
    ij = np.array([[0, 0], [1, 1], [2, 2]])
    pred = T_true[:3, 3] + np.r_[0.03 * along, 0.0]
    args = (p, c, T_true[:3, :3], ij, pred, 0.9, 0.003, 0.03, 0.09)
    fit = plane_translation(*args, unmeasured="prediction", prediction_var=0.02**2,
                            predicted=pred)  # fmt: skip
    assert not fit.measured  # kept: the planes' weak direction, within 2 deg of the wall's
    assert abs((fit.t[:2] - pred[:2]) @ along) < 1e-3
    if bias_m:
        exact = plane_translation(*_ground_and_wall(0.0)[:2], *args[2:])
        prior = plane_translation(*args)
        assert abs((prior.t[:2] - exact.t[:2]) @ along) > 0.05


def test_a_degenerate_epoch_keeps_the_prediction_through_the_solver():
    """``odometry.refine_unmeasured: prediction`` through the solver with the prior's
    sigma: degenerate, the along-wall step the prior's, across the wall the truth's, and
    the step's covariance along the wall the prior's sigma squared plus the floor;
    without the sigma, as "prior"."""
    p, c, T_true, along = _ground_and_wall()
    prior = T_true.copy()
    prior[:2, 3] += 0.05 * along
    cfg = PlanodomConfig().updated({"odometry.refine_unmeasured": "prediction"})
    r = estimate_relative_pose(p, c, cfg, prior, prior_sigma_m=0.02)
    assert r.status is Status.DEGENERATE
    assert abs((r.T_prev_curr[:2, 3] - prior[:2, 3]) @ along) < 1e-12
    normal = np.array([along[1], -along[0]])
    assert abs((r.T_prev_curr[:2, 3] - T_true[:2, 3]) @ normal) < 1e-6
    floor = cfg.odometry.min_sigma_translation_m
    assert along @ r.covariance[3:, 3:] @ along == pytest.approx(0.02**2 + floor**2, rel=1e-3)
    a = estimate_relative_pose(p, c, cfg, prior)
    b = estimate_relative_pose(p, c, cfg.updated({"odometry.refine_unmeasured": "prior"}), prior)
    np.testing.assert_array_equal(a.T_prev_curr, b.T_prev_curr)
