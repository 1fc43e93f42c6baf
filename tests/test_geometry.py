"""Geometry core: closed forms, gtsam agreement and property tests on random poses and planes."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planodom import geometry as g
from planodom import se3
from planodom.errors import GeometryError

seeds = st.integers(min_value=0, max_value=2**32 - 1)


def random_pose(rng: np.random.Generator, scale: float = 20.0) -> np.ndarray:
    R = Rotation.random(random_state=rng).as_matrix()
    return g.make_transform(R, rng.uniform(-scale, scale, 3))


def random_plane(rng: np.random.Generator) -> g.Plane:
    n = rng.normal(size=3)
    return g.Plane(n / np.linalg.norm(n), rng.uniform(-30, 30))


def points_on(plane: g.Plane, rng: np.random.Generator, k: int = 50) -> np.ndarray:
    """Points on ``plane`` built independently of Plane.distance: -d n + in-plane offsets."""
    a = np.cross(plane.normal, [1.0, 0, 0])
    if np.linalg.norm(a) < 0.1:
        a = np.cross(plane.normal, [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(plane.normal, a)
    uv = rng.uniform(-10, 10, (k, 2))
    return -plane.offset * plane.normal + uv[:, :1] * a + uv[:, 1:] * b


def nearly_parallel(n1: np.ndarray, n2: np.ndarray, min_angle: float) -> bool:
    """True when the unoriented angle between two normals is below ``min_angle`` rad."""
    return float(np.linalg.norm(np.cross(n1, n2))) < np.sin(min_angle)


def angle_between(n1: np.ndarray, n2: np.ndarray) -> float:
    """Angle (rad, in [0, pi]) by atan2 of |n1 x n2| and n1 . n2 (not arccos, as the code)."""
    return float(np.arctan2(np.linalg.norm(np.cross(n1, n2)), np.dot(n1, n2)))


@given(seeds)
def test_transform_round_trip(seed: int) -> None:
    rng = np.random.default_rng(seed)
    T = random_pose(rng)
    pts = rng.uniform(-5, 5, (10, 3))
    back = g.transform_points(g.invert_transform(T), g.transform_points(T, pts))
    np.testing.assert_allclose(back, pts, atol=1e-9)
    np.testing.assert_allclose(g.invert_transform(T) @ T, np.eye(4), atol=1e-12)


@given(seeds)
def test_plane_transform_keeps_points_on_plane(seed: int) -> None:
    rng = np.random.default_rng(seed)
    plane_b, T_a_b = random_plane(rng), random_pose(rng)
    pts_b = points_on(plane_b, rng)
    plane_a = plane_b.transformed(T_a_b)
    np.testing.assert_allclose(plane_a.distance(g.transform_points(T_a_b, pts_b)), 0, atol=1e-9)
    # Orientation follows the transform: a point on the positive side stays there.
    probe_b = pts_b[0] + 2.0 * plane_b.normal
    assert plane_a.distance(g.transform_points(T_a_b, probe_b[None]))[0] == pytest.approx(2.0)
    # Round trip.
    back = plane_a.transformed(g.invert_transform(T_a_b))
    np.testing.assert_allclose(back.coefficients, plane_b.coefficients, atol=1e-9)


@given(seeds)
def test_plane_transform_matches_gtsam(seed: int) -> None:
    rng = np.random.default_rng(seed)
    plane_world, T_world_base = random_plane(rng), random_pose(rng)
    # gtsam's OrientedPlane3.transform(T_world_base) gives the plane in the base frame.
    expected = gtsam.OrientedPlane3(plane_world.coefficients).transform(gtsam.Pose3(T_world_base))
    ours = plane_world.transformed(g.invert_transform(T_world_base))
    np.testing.assert_allclose(ours.coefficients, expected.planeCoefficients(), atol=1e-9)


@given(seeds)
def test_dihedral_angles_invariant_under_rigid_motion(seed: int) -> None:
    rng = np.random.default_rng(seed)
    planes = [random_plane(rng) for _ in range(6)]
    T = random_pose(rng)
    before = g.dihedral_angles(np.stack([p.normal for p in planes]))
    after = g.dihedral_angles(np.stack([p.transformed(T).normal for p in planes]))
    np.testing.assert_allclose(after, before, atol=1e-7)
    expected = [[angle_between(p.normal, q.normal) for q in planes] for p in planes]
    np.testing.assert_allclose(before, expected, atol=1e-7)


def test_dihedral_angles_closed_form() -> None:
    n1 = np.array([1.0, 0, 0])
    n2 = np.array([np.cos(0.3), np.sin(0.3), 0])
    a = np.pi - 0.3
    expected = [[0.0, 0.3, np.pi], [0.3, 0.0, a], [np.pi, a, 0.0]]
    np.testing.assert_allclose(g.dihedral_angles(np.stack([n1, n2, -n1])), expected, atol=1e-7)


@given(seeds)
def test_rotation_frames_recover_rotation(seed: int) -> None:
    """Paper eq. 1: frames of the same plane pairs seen in two frames give R = U_prev U_curr^T."""
    rng = np.random.default_rng(seed)
    planes = [random_plane(rng) for _ in range(8)]
    pairs = [(p, q) for p, q in zip(planes[::2], planes[1::2], strict=True)]
    pairs.append((planes[0], planes[0].flipped()))  # parallel: a NaN frame, others unharmed
    T_prev_curr = random_pose(rng)
    T_curr_prev = g.invert_transform(T_prev_curr)
    n1 = np.stack([p.normal for p, _ in pairs])
    n2 = np.stack([q.normal for _, q in pairs])
    U_prev = g.rotation_frames(n1, n2)
    U_curr = g.rotation_frames(n1 @ T_curr_prev[:3, :3].T, n2 @ T_curr_prev[:3, :3].T)
    assert np.isnan(U_prev[-1]).any() and np.isnan(U_curr[-1]).any()
    for k, (p, q) in enumerate(pairs[:-1]):
        if nearly_parallel(p.normal, q.normal, np.radians(1)):
            continue
        # Gram-Schmidt of (n1, n2) and their cross product: the frame built independently.
        u2 = q.normal - (q.normal @ p.normal) * p.normal
        u2 /= np.linalg.norm(u2)
        expected = np.column_stack([p.normal, u2, np.cross(p.normal, u2)])
        np.testing.assert_allclose(U_prev[k], expected, atol=1e-8)
        assert np.linalg.det(U_prev[k]) == pytest.approx(1.0)
        R = U_prev[k] @ U_curr[k].T
        np.testing.assert_allclose(R, T_prev_curr[:3, :3], atol=1e-8)


def test_rotation_frame_is_papers_U_for_orthogonal_normals() -> None:
    n1, n2 = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    U = np.column_stack([n1, n2, [0, 0, 1]])
    np.testing.assert_allclose(g.rotation_frames(n1[None], n2[None])[0], U)
    assert np.isnan(g.rotation_frames(n1[None], n1[None])).any()


def test_reference_points_of_walls_closed_form() -> None:
    # Walls x = 3 (normal -x towards origin, d = 3) and y = -2 (normal +y, d = 2): corner (3, -2).
    # Wall and ground meet in a horizontal line, two parallel walls in none: no reference point.
    wall_x, wall_y, ground = np.array([-1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])
    refs = g.horizontal_reference_points(
        np.stack([wall_x, wall_x, wall_x]),
        np.array([3.0, 3.0, 3.0]),
        np.stack([wall_y, ground, -wall_x]),
        np.array([2.0, 1.5, 5.0]),
    )
    np.testing.assert_allclose(refs[0], [3.0, -2.0])
    assert np.isnan(refs[1:]).all()


@given(seeds)
def test_reference_points_lie_on_both_planes(seed: int) -> None:
    """The reference point (x, y, 0) is where the pair's intersection line crosses z = 0."""
    rng = np.random.default_rng(seed)
    p1 = [random_plane(rng) for _ in range(5)]
    p2 = [random_plane(rng) for _ in range(5)]
    n1, n2 = np.stack([p.normal for p in p1]), np.stack([p.normal for p in p2])
    d1, d2 = np.array([p.offset for p in p1]), np.array([p.offset for p in p2])
    refs = g.horizontal_reference_points(n1, d1, n2, d2, 0.2)
    v = np.cross(n1, n2)
    defined = np.abs(v[:, 2]) >= 0.2 * np.linalg.norm(v, axis=1)
    np.testing.assert_array_equal(np.isfinite(refs).all(axis=1), defined)
    points = np.column_stack([refs, np.zeros(5)])[defined]
    np.testing.assert_allclose(np.einsum("ij,ij->i", n1[defined], points), -d1[defined], atol=1e-7)
    np.testing.assert_allclose(np.einsum("ij,ij->i", n2[defined], points), -d2[defined], atol=1e-7)


@given(seeds)
def test_reference_point_moves_by_minus_horizontal_translation(seed: int) -> None:
    """Paper eq. 2: with the rotation removed, the reference point moves by -T (tz = 0)."""
    rng = np.random.default_rng(seed)
    # Tilted but steep walls (as seen from a rolling, pitching vehicle).
    normals = []
    for _ in range(2):
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(-0.3, 0.3)
        normals.append(np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)]))
    if nearly_parallel(normals[0], normals[1], np.radians(10)):
        return
    planes = [g.Plane(n, rng.uniform(1, 30)) for n in normals]
    t = np.array([*rng.uniform(-3, 3, 2), 0.0])
    T_prev_curr = g.make_transform(np.eye(3), t)
    moved = [p.transformed(g.invert_transform(T_prev_curr)) for p in planes]
    w_prev, w_curr = (
        g.horizontal_reference_points(
            ps[0].normal, np.array([ps[0].offset]), ps[1].normal, np.array([ps[1].offset]), 0.0
        )[0]
        for ps in (planes, moved)
    )
    np.testing.assert_allclose(w_curr, w_prev - t[:2], atol=1e-7)


def test_plane_validation_and_normalisation() -> None:
    p = g.Plane(np.array([0, 0, 2.0]), 4.0)
    np.testing.assert_allclose(p.coefficients, [0, 0, 1, 2])
    with pytest.raises(GeometryError, match="zero length"):
        g.Plane(np.zeros(3), 1.0)
    for bad in (np.nan, np.inf, -np.inf):
        with pytest.raises(GeometryError, match="finite"):
            g.Plane(np.array([bad, 0, 1]), 1.0)
        with pytest.raises(GeometryError, match="finite"):
            g.Plane(np.array([0, 1, 0.0]), bad)
    with pytest.raises(GeometryError, match="finite"):
        g.Plane(np.array([0, 1.0]), 1.0)
    with pytest.raises(GeometryError, match="confidence"):
        g.Plane(np.array([0, 0, 1.0]), 1.0, confidence=0.0)


def test_orientation_rules() -> None:
    # Ground 1.5 m below a sensor at the origin: oriented towards the sensor, n = +z, d = 1.5.
    ground = g.Plane(np.array([0, 0, -1.0]), -1.5).oriented_towards(np.zeros(3))
    np.testing.assert_allclose(ground.coefficients, [0, 0, 1, 1.5])
    assert ground.flipped().flipped().coefficients.tolist() == ground.coefficients.tolist()
    np.testing.assert_allclose(ground.closest_point(), [0, 0, -1.5])


@given(seeds)
def test_rpy_and_pose5_round_trip(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rpy = rng.uniform([-1, -1.4, -3], [1, 1.4, 3])
    xyz = rng.uniform(-5, 5, 3)
    T = g.transform_from_rpy_xyz(*rpy, *xyz)
    np.testing.assert_allclose(g.rpy_from_rotation(T[:3, :3]), rpy, atol=1e-9)
    np.testing.assert_allclose(g.pose5_from_transform(T), [*rpy, *xyz[:2]], atol=1e-9)
    # Closed form for yaw only.
    Ty = g.transform_from_rpy_xyz(0, 0, 0.5, 1, 2)
    c, s = np.cos(0.5), np.sin(0.5)
    np.testing.assert_allclose(Ty[:2, :2], [[c, -s], [s, c]])


@settings(max_examples=30)
@given(seeds)
def test_covariance_follows_transform(seed: int) -> None:
    """Transformed covariance equals the sample covariance of transformed samples."""
    rng = np.random.default_rng(seed)
    plane, T = random_plane(rng), random_pose(rng, 5.0)
    A = rng.normal(size=(4, 4)) * 1e-3
    cov = A @ A.T
    samples = rng.multivariate_normal(plane.coefficients, cov, size=4000)
    moved = np.array(
        [
            np.append(*[x.ravel() for x in g.transform_planes(T, s[None, :3], s[3:])])
            for s in samples
        ]
    )
    expected = np.cov(moved.T)
    got = g.Plane(plane.normal, plane.offset, covariance=cov).transformed(T).covariance
    # Sampled in unnormalised (n, d): the map is linear, so the match is statistical only.
    np.testing.assert_allclose(got, expected, atol=6 * np.abs(expected).max() / np.sqrt(4000))


def test_plane_tangent_covariance() -> None:
    cov = np.diag([1e-4, 2e-4, 0.0, 4e-4])  # no variance along n = z
    p = g.Plane(np.array([0, 0, 1.0]), 2.0, covariance=cov)
    tc = g.plane_tangent_covariance(p)
    B = np.asarray(gtsam.Unit3(p.normal).basis())
    np.testing.assert_allclose(tc[:2, :2], B.T @ cov[:3, :3] @ B)
    assert tc[2, 2] == pytest.approx(4e-4)
    with pytest.raises(GeometryError):
        g.plane_tangent_covariance(g.Plane(np.array([0, 0, 1.0]), 2.0))


def test_support_area_and_transform() -> None:
    square = np.array([[0, 0, 0], [2, 0, 0], [2, 3, 0], [0, 3, 0.0]])
    s = g.PlaneSupport(square.mean(axis=0), square, 4)
    assert s.area == pytest.approx(6.0)
    T = random_pose(np.random.default_rng(3))
    assert s.transformed(T).area == pytest.approx(6.0)


def test_compiled_se3_log_matches_its_numpy_form_and_scipy_fallback():
    """se3_log runs compiled; its numpy form (kept for rotations scipy orthogonalises
    first) must give the same twists (the same bits where they were written: the same
    operations in the same order), over rotation angles from 1e-9 rad (the series) to
    3 rad, batched and one by one, with a non-orthonormal rotation in the batch."""
    rng = np.random.default_rng(1)
    n = 3000
    angle = rng.choice([1e-9, 1e-7, 1e-5, 1e-3, 0.1, 1.0, 3.0], n)[:, None]
    rv = rng.normal(size=(n, 3))
    rv *= angle / np.linalg.norm(rv, axis=1, keepdims=True)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(rv).as_matrix()
    T[:, :3, 3] = rng.normal(size=(n, 3))
    T[5, :3, :3] *= 1.001  # scipy orthogonalises it: the numpy form's row
    batched = g.se3_log(T)
    np.testing.assert_allclose(batched, se3._se3_log_rows(T), rtol=1e-14, atol=1e-20)
    one = np.array([g.se3_log(T[k]) for k in range(50)])
    np.testing.assert_array_equal(one, batched[:50])
    np.testing.assert_allclose(batched[:, :3], rv, rtol=1e-9, atol=1e-15)  # rows but 5
    np.testing.assert_allclose(g.se3_exp(batched[10]), T[10], atol=1e-12)


def test_twist_step_is_the_exponential_of_the_twist_over_dt_bit_for_bit():
    """The remembered constant-velocity step equals ``se3_exp(twist * dt)`` exactly, for a
    new twist and for one asked again, and cannot be changed by a caller."""
    rng = np.random.default_rng(5)
    for _ in range(5):
        twist, dt = rng.normal(size=6), float(rng.uniform(0.01, 0.2))
        for _again in range(2):
            step = g.twist_step(twist.copy(), dt)
            assert step.tobytes() == g.se3_exp(twist * dt).tobytes()
        assert not step.flags.writeable
    assert g.twist_step(twist, dt + 1e-9).tobytes() == g.se3_exp(twist * (dt + 1e-9)).tobytes()


def test_cross_rows_equals_numpy_cross_bit_for_bit_when_broadcast():
    """:func:`cross_rows` gives numpy's bits, broadcast over leading axes too (the plane
    map's moment Jacobians cross (M, 3, 3) with (M, 1, 3))."""
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(40, 3, 3)) * 7.0, rng.normal(size=(40, 1, 3))
    assert np.array_equal(g.cross_rows(a, b), np.cross(a, b))
    assert np.array_equal(g.cross_rows(a[:, 0], b[:, 0]), np.cross(a[:, 0], b[:, 0]))


def test_one_rotation_check_with_a_documented_bound() -> None:
    """planodom.geometry.non_rotations / rotation_problem, the check every reader of a
    rotation block shares (KITTI poses and Tr, rig.yaml extrinsics, simulated sensors)."""
    rng = np.random.default_rng(5)
    R = Rotation.random(4, random_state=rng).as_matrix()
    assert len(g.non_rotations(R)) == 0
    assert g.rotation_problem(R[0]) is None
    # six and four written decimals are rotations (off by ~1e-6 and ~1e-4)
    assert len(g.non_rotations(np.round(R, 6))) == 0
    assert len(g.non_rotations(np.round(R, 4))) == 0
    # the bound: a column scaled by s moves (R^T R)_00 to s^2
    within, beyond = R[0].copy(), R[0].copy()
    within[:, 0] *= np.sqrt(1 + 0.9e-3)
    beyond[:, 0] *= np.sqrt(1 + 1.1e-3)
    assert len(g.non_rotations(within)) == 0 and list(g.non_rotations(beyond)) == [0]
    bad = R.copy()
    bad[1][:, 0] *= 1.002
    bad[2] = np.diag([1.0, 1.0, -1.0])  # reflection
    bad[3, :, 0] = bad[3, :, 0] + 0.1 * bad[3, :, 1]  # shear, unit columns kept
    bad[3, :, 0] /= np.linalg.norm(bad[3, :, 0])
    assert list(g.non_rotations(bad)) == [1, 2, 3]
    assert "column norms" in (g.rotation_problem(bad[1]) or "")
    assert "reflection" in (g.rotation_problem(bad[2]) or "")
    assert "not orthogonal" in (g.rotation_problem(bad[3]) or "")
    assert "not finite" in (g.rotation_problem(np.full((3, 3), np.nan)) or "")
    assert g.ROTATION_TOL == 1e-3
    # the first block that is none, why, and how many are not (the readers' one message)
    assert g.first_non_rotation(R) is None
    first = g.first_non_rotation(bad)
    assert first is not None and first[0] == 1 and "column norms" in first[1] and first[2] == 3


def test_rpy_of_rotations_is_scipys_with_its_checks_skipped_only_when_they_pass() -> None:
    """``rpy_from_rotation`` skips scipy's validity checks for matrices that pass them:
    the same angles as scipy with its checks, for rotations, for matrices a little off
    SO(3) (which scipy projects with an SVD) and for a batch mixing both."""
    rng = np.random.default_rng(4)
    R = Rotation.random(200, random_state=5).as_matrix()
    off = R + rng.normal(0, 1e-9, R.shape)  # scipy projects these on SO(3)
    for M in (R, off, np.concatenate([R[:3], off[:1]])):
        expected = Rotation.from_matrix(M).as_euler("ZYX")[:, ::-1]
        assert g.rpy_from_rotation(M).tobytes() == expected.tobytes()
    assert g._surely_rotations(R) and not g._surely_rotations(off[:1])
    with pytest.raises(ValueError, match="determinant"):
        g.rpy_from_rotation(-R[0])  # left-handed: scipy's error, as before


@pytest.mark.parametrize("seed", range(5))
def test_vector_norm_has_np_linalg_norms_bits(seed: int) -> None:
    v = np.random.default_rng(seed).normal(size=2 + seed % 2) * 10.0 ** (seed - 2)
    assert g.vector_norm(v) == np.linalg.norm(v)
    assert g.vector_norm(np.array([3.0, 4.0])) == 5.0


def test_row_norms_equal_numpy_bit_for_bit_on_every_layout() -> None:
    rng = np.random.default_rng(3)
    base = rng.normal(size=(20_000, 4)) * rng.exponential(size=(20_000, 1)) * 30
    for x in (
        np.ascontiguousarray(base[:, :3]),
        np.asfortranarray(base[:, :3]),
        base[:, 1:],  # a strided view
        base[::3, :3],
        base[:, :3].astype(np.float32),
        np.array([[np.inf, 1.0, 2.0], [np.nan, 1.0, 1.0], [0.0, -0.0, 0.0], [1e-200, 1e-200, 0]]),
    ):
        want = np.linalg.norm(x, axis=1)
        got = g.row_norms(x)
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes()
    # The order of the sum matters: another order differs in the last bit on many rows.
    x = np.ascontiguousarray(base[:, :3])
    other = np.sqrt(x[:, 0] ** 2 + (x[:, 1] ** 2 + x[:, 2] ** 2))
    assert np.any(other != np.linalg.norm(x, axis=1))
    two = base[:, :2]  # another shape: numpy's own
    assert g.row_norms(two).tobytes() == np.linalg.norm(two, axis=1).tobytes()
