"""The refinement over the associated planes' points (planodom.odometry.moment_refine)."""

import numpy as np

from planodom.config import OdometryConfig
from planodom.geometry import (
    Plane,
    PlaneSupport,
    invert_transform,
    orthonormalised,
    pose5_from_transform,
    se3_exp,
    se3_log,
)
from planodom.odometry.moment_refine import mahalanobis2, moment_refined, offset_translated
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet

#: Surfaces in the previous frame: (unit normal, offset), n . p + d = 0, and two in-plane axes.
SURFACES = [
    (np.array([0.0, 0.0, 1.0]), 1.0),  # the ground, 1 m below
    (np.array([1.0, 0.0, 0.0]), -6.0),  # a wall ahead
    (np.array([0.0, 1.0, 0.0]), -4.0),  # a wall to the left
    (np.array([np.cos(0.5), -np.sin(0.5), 0.0]), 3.0),  # a wall behind, right
]


def _points(normal: np.ndarray, offset: float, rng: np.random.Generator) -> np.ndarray:
    """(300, 3) points of the plane within a 3 m patch around its foot point."""
    u = np.cross(normal, [0.3, 0.5, 0.8])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    ab = rng.uniform(-1.5, 1.5, (300, 2))
    return -offset * normal + ab[:, :1] * u + ab[:, 1:] * v


def _plane(points: np.ndarray) -> Plane:
    """The TLS plane of ``points`` (N, 3) with their moments."""
    c = points.mean(axis=0)
    S = (points - c).T @ (points - c)
    n = np.linalg.eigh(S)[1][:, 0]
    support = PlaneSupport(c, n_points=len(points), scatter=S)
    return Plane(n, float(-n @ c), support=support)


def _epochs(T_prev_curr: np.ndarray, noise: float = 0.0):
    """The planes of both epochs: the surfaces' points in each frame (curr = T^-1 prev)."""
    rng = np.random.default_rng(3)
    T_curr_prev = invert_transform(T_prev_curr)
    prev, curr = [], []
    for n, d in SURFACES:
        p = _points(n, d, rng)
        q = p @ T_curr_prev[:3, :3].T + T_curr_prev[:3, 3]
        prev.append(_plane(p + noise * rng.standard_normal(p.shape)))
        curr.append(_plane(q + noise * rng.standard_normal(q.shape)))
    return prev, curr


def test_an_ok_estimate_goes_to_the_truth():
    truth = se3_exp(np.array([0.002, -0.001, 0.03, 0.8, 0.05, 0.01]))
    prev, curr = _epochs(truth)
    start = truth @ se3_exp(np.array([0.004, 0.003, -0.01, 0.03, -0.04, 0.02]))
    ij = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
    result = RelativePose(start, None, Status.OK, ij)
    out = moment_refined(result, prev, curr, OdometryConfig())
    assert np.abs(se3_log(invert_transform(truth) @ out.T_prev_curr)).max() < 1e-8
    assert out.status is Status.OK and out.covariance is None


def test_noise_moves_it_little():
    truth = se3_exp(np.array([0.0, 0.0, 0.02, 0.5, 0.0, 0.0]))
    prev, curr = _epochs(truth, noise=0.01)
    start = truth @ se3_exp(np.array([0.0, 0.0, 0.01, 0.02, 0.02, 0.0]))
    result = RelativePose(start, None, Status.OK, np.array([[0, 0], [1, 1], [2, 2], [3, 3]]))
    err = se3_log(
        invert_transform(truth) @ moment_refined(result, prev, curr, OdometryConfig()).T_prev_curr
    )
    # the start is 0.57 deg and 2.8 cm off; 1 cm noise on 300 points a plane leaves ~0.07 deg
    assert np.degrees(np.linalg.norm(err[:3])) < 0.15 and np.linalg.norm(err[3:]) < 0.005


def test_kept_when_not_ok_too_few_or_too_far():
    truth = se3_exp(np.array([0.0, 0.0, 0.02, 0.5, 0.0, 0.0]))
    prev, curr = _epochs(truth)
    ij = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
    start = truth @ se3_exp(np.array([0.0, 0.0, 0.0, 0.03, 0.0, 0.0]))
    cfg = OdometryConfig()
    degenerate = RelativePose(start, None, Status.DEGENERATE, ij)
    assert moment_refined(degenerate, prev, curr, cfg) is degenerate
    two = RelativePose(start, None, Status.OK, ij[:2])
    assert moment_refined(two, prev, curr, cfg) is two
    far = RelativePose(start, None, Status.OK, ij)  # 3 cm off: beyond a 1 cm inlier bound
    tight = cfg.model_copy(update={"translation_inlier_m": 0.01})
    assert moment_refined(far, prev, curr, tight) is far
    bare = [Plane(p.normal, p.offset) for p in prev]  # no moments
    assert moment_refined(far, bare, curr, cfg) is far


def test_the_chi_square_gate_keeps_what_the_covariance_says_is_too_far():
    truth = se3_exp(np.array([0.0, 0.0, 0.02, 0.5, 0.0, 0.0]))
    prev, curr = _epochs(truth)
    ij = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
    start = truth @ se3_exp(np.array([0.0, 0.0, 0.0, 0.03, 0.0, 0.0]))  # 3 cm off in x
    gated = OdometryConfig().model_copy(update={"moment_gate_chi2": 20.5})
    # x sigma 1 cm: the refinement's 3 cm move is 9 (chi-square), within 20.5: to the truth
    loose = RelativePose(start, np.diag([1e-4] * 3 + [1e-4, 1e-4]), Status.OK, ij)
    out = moment_refined(loose, prev, curr, gated)
    assert np.abs(se3_log(invert_transform(truth) @ out.T_prev_curr)).max() < 1e-8
    # x sigma 5 mm: the same move is 36: the consensus is kept
    tight = RelativePose(start, np.diag([1e-4] * 3 + [2.5e-5, 1e-4]), Status.OK, ij)
    assert moment_refined(tight, prev, curr, gated) is tight
    # without the gate (the default) the covariance is not consulted
    assert moment_refined(tight, prev, curr, OdometryConfig()) is not tight


def test_the_distance_is_in_the_covariances_parameters():
    T0 = se3_exp(np.array([0.0, 0.0, 0.5, 1.0, 2.0, 0.0]))
    T = T0.copy()
    T[:2, 3] += [0.03, -0.04]  # 5 cm in the previous frame's x, y
    T[:3, :3] = T0[:3, :3] @ se3_exp(np.array([0.0, 0.0, 0.01, 0, 0, 0]))[:3, :3]  # yaw + 0.01
    cov = np.diag([1e-4, 1e-4, 1e-4, 1e-4, 1e-4])
    # (0.01^2 + 0.03^2 + 0.04^2) / 1e-4 = 1 + 9 + 16
    assert abs(mahalanobis2(T0, T, cov) - 26.0) < 1e-9


def test_offsets_take_the_rotation_and_fit_the_translation_to_the_offsets():
    truth = se3_exp(np.array([0.002, -0.001, 0.03, 0.8, 0.05, 0.01]))
    prev, curr = _epochs(truth)
    ij = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
    cfg = OdometryConfig().model_copy(update={"moment_translation": "offsets"})
    sets = (PlaneSet.from_planes(prev), PlaneSet.from_planes(curr))
    # the consensus's rotation 0.3 deg off, its translation true: both to the truth
    start = truth.copy()
    start[:3, :3] = se3_exp(np.array([0.003, -0.002, 0.004, 0, 0, 0]))[:3, :3] @ truth[:3, :3]
    out = moment_refined(RelativePose(start, None, Status.OK, ij), prev, curr, cfg, sets)
    assert np.abs(se3_log(invert_transform(truth) @ out.T_prev_curr)).max() < 1e-8


def _seen(k: int, T_world_k: np.ndarray, tilt: float, rng: np.random.Generator) -> list[Plane]:
    """Epoch ``k``'s planes of :data:`SURFACES` (world frame) in its frame ``T_world_k``, each
    from a stretch 3.6 m farther along the surface than epoch ``k - 1``'s, every plane
    tilted about its centroid by ``tilt`` rad about a random axis (a deskewing error)."""
    out = []
    T_k_world = invert_transform(T_world_k)
    for n, d in SURFACES:
        u = np.cross(n, [0.3, 0.5, 0.8])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        ab = rng.uniform(-1.5, 1.5, (300, 2)) + [3.0 * k, -2.0 * k]
        q = (-d * n + ab[:, :1] * u + ab[:, 1:] * v) @ T_k_world[:3, :3].T + T_k_world[:3, 3]
        c = q.mean(axis=0)
        tilted = se3_exp(np.r_[tilt * rng.standard_normal(3), 0.0, 0.0, 0.0])[:3, :3]
        out.append(_plane((q - c) @ tilted.T + c))
    return out


def test_offsets_cancel_an_epochs_plane_errors_between_its_two_steps():
    # Epoch 1's planes tilted by ~3 mrad about their centroids, 5-10 m from its origin;
    # each step's translation fitted under its true rotation from a 1 cm error. The steps
    # into and out of epoch 1 then err by 2 cm in x, y, with opposite signs: the two
    # together are off by less than a quarter of one (what is left is second order: the
    # tilt times the 1-2 m steps, where errors of one sign would add to 4 cm).
    rng = np.random.default_rng(5)
    T_world = [np.eye(4), se3_exp(np.array([0, 0, 0.02, 1.0, 0, 0])),
               se3_exp(np.array([0, 0, 0.04, 2.0, 0.05, 0]))]  # fmt: skip
    epochs = [_seen(k, T, 0.003 if k == 1 else 0.0, rng) for k, T in enumerate(T_world)]
    ij = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
    cfg = OdometryConfig()
    both, xy_step = np.eye(4), []
    for k in (1, 2):
        truth = invert_transform(T_world[k - 1]) @ T_world[k]
        start = truth.copy()
        start[:2, 3] += 0.01
        sets = (PlaneSet.from_planes(epochs[k - 1]), PlaneSet.from_planes(epochs[k]))
        T = offset_translated(truth, start, sets, ij, cfg)
        assert np.array_equal(T[:3, :3], truth[:3, :3])
        xy_step.append(np.linalg.norm(T[:2, 3] - truth[:2, 3]))
        both = both @ T
    assert min(xy_step) > 0.01
    assert np.linalg.norm(both[:2, 3] - T_world[2][:2, 3]) < xy_step[0] / 4


def test_the_distance_is_scipys_angles_difference_to_rounding():
    """The closed-form angles give the distance of scipy's ZYX angles (an independent
    computation) to rounding, also across the +-180 deg wrap of the yaw."""
    rng = np.random.default_rng(9)
    cov = np.diag([1e-4, 1e-4, 4e-4, 1e-3, 1e-3])
    for i in range(200):
        T0 = se3_exp(rng.normal(size=6) * [0.05, 0.05, 0.3, 1.0, 1.0, 0.05])
        if i % 4 == 0:
            T0 = se3_exp(np.array([0.01, -0.02, np.pi - 2e-4, 1.0, 2.0, 0.0]))  # the wrap
        T = orthonormalised(T0 @ se3_exp(rng.normal(size=6) * 1e-3))
        d = pose5_from_transform(T) - pose5_from_transform(T0)
        d[:3] = np.angle(np.exp(1j * d[:3]))
        want = float(d @ np.linalg.solve(cov, d))
        assert abs(mahalanobis2(T0, T, cov) - want) <= 1e-9 * want + 1e-12
    assert mahalanobis2(np.eye(4), se3_exp(np.full(6, 0.01)), np.zeros((5, 5))) == np.inf
