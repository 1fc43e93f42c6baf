"""Geometry core: closed forms, gtsam agreement and property tests on random poses and planes."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planodom import geometry as g
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
    expected = g.plane_to_gtsam(plane_world).transform(g.pose_to_gtsam(T_world_base))
    ours = plane_world.transformed(g.invert_transform(T_world_base))
    np.testing.assert_allclose(ours.coefficients, expected.planeCoefficients(), atol=1e-9)


@given(seeds)
def test_dihedral_angles_invariant_under_rigid_motion(seed: int) -> None:
    rng = np.random.default_rng(seed)
    planes = [random_plane(rng) for _ in range(6)]
    T = random_pose(rng)
    before = g.dihedral_angles(g.stack_planes(planes)[0])
    after = g.dihedral_angles(g.stack_planes([p.transformed(T) for p in planes])[0])
    np.testing.assert_allclose(after, before, atol=1e-7)
    assert g.dihedral_angle(planes[0].normal, planes[1].normal) == pytest.approx(before[0, 1])


def test_dihedral_angle_closed_form() -> None:
    n1 = np.array([1.0, 0, 0])
    n2 = np.array([np.cos(0.3), np.sin(0.3), 0])
    assert g.dihedral_angle(n1, n2) == pytest.approx(0.3)
    assert g.dihedral_angle(n1, -n1) == pytest.approx(np.pi)
    assert g.are_parallel(n1, -n1, np.radians(5))
    assert not g.are_parallel(n1, n2, np.radians(5))


@given(seeds)
def test_rotation_from_frames_recovers_rotation(seed: int) -> None:
    rng = np.random.default_rng(seed)
    p1, p2 = random_plane(rng), random_plane(rng)
    if g.are_parallel(p1.normal, p2.normal, np.radians(1)):
        return
    T_prev_curr = random_pose(rng)
    T_curr_prev = g.invert_transform(T_prev_curr)
    q1, q2 = p1.transformed(T_curr_prev), p2.transformed(T_curr_prev)
    U_prev = g.rotation_frame(p1.normal, p2.normal)
    U_curr = g.rotation_frame(q1.normal, q2.normal)
    np.testing.assert_allclose(U_prev.T @ U_prev, np.eye(3), atol=1e-9)
    assert np.linalg.det(U_prev) == pytest.approx(1.0)
    R = g.rotation_from_frames(U_prev, U_curr)
    np.testing.assert_allclose(R, T_prev_curr[:3, :3], atol=1e-8)
    batched = g.rotation_frames(p1.normal[None], p2.normal[None])[0]
    np.testing.assert_allclose(batched, U_prev, atol=1e-12)


def test_rotation_frame_is_papers_U_for_orthogonal_normals() -> None:
    n1, n2 = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    np.testing.assert_allclose(g.rotation_frame(n1, n2), np.column_stack([n1, n2, [0, 0, 1]]))
    with pytest.raises(GeometryError):
        g.rotation_frame(n1, 2 * n1)
    assert np.isnan(g.rotation_frames(n1[None], n1[None])).any()


@given(seeds)
def test_intersection_line_lies_on_both_planes(seed: int) -> None:
    rng = np.random.default_rng(seed)
    p1, p2 = random_plane(rng), random_plane(rng)
    if g.are_parallel(p1.normal, p2.normal, np.radians(1)):
        return
    p, v = g.intersection_line(p1.normal, p1.offset, p2.normal, p2.offset)
    line = p + np.outer(np.linspace(-10, 10, 5), v)
    np.testing.assert_allclose(p1.distance(line), 0, atol=1e-7)
    np.testing.assert_allclose(p2.distance(line), 0, atol=1e-7)
    assert abs(p @ v) < 1e-7  # closest point to the origin


def test_intersection_line_of_parallel_planes_raises() -> None:
    with pytest.raises(GeometryError):
        g.intersection_line(np.array([0, 0, 1.0]), 1.0, np.array([0, 0, 1.0]), 2.0)


def test_reference_point_of_two_walls_closed_form() -> None:
    # Walls x = 3 (normal -x towards origin, d = 3) and y = -2 (normal +y, d = 2): corner (3, -2).
    n1, n2 = np.array([-1.0, 0, 0]), np.array([0, 1.0, 0])
    np.testing.assert_allclose(g.horizontal_reference_point(n1, 3.0, n2, 2.0), [3.0, -2.0])
    # Wall and ground meet in a horizontal line: no reference point.
    assert np.isnan(g.horizontal_reference_point(n1, 3.0, np.array([0, 0, 1.0]), 1.5)).all()


@given(seeds)
def test_reference_point_moves_by_minus_horizontal_translation(seed: int) -> None:
    """Paper eq. 2: with the rotation removed, the reference point moves by -T (tz = 0)."""
    rng = np.random.default_rng(seed)
    # Tilted but steep walls (as seen from a rolling, pitching vehicle).
    normals = []
    for _ in range(2):
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(-0.3, 0.3)
        normals.append(np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)]))
    if g.are_parallel(normals[0], normals[1], np.radians(10)):
        return
    planes = [g.Plane(n, rng.uniform(1, 30)) for n in normals]
    t = np.array([*rng.uniform(-3, 3, 2), 0.0])
    T_prev_curr = g.make_transform(np.eye(3), t)
    moved = [p.transformed(g.invert_transform(T_prev_curr)) for p in planes]
    w_prev = g.horizontal_reference_point(
        planes[0].normal, planes[0].offset, planes[1].normal, planes[1].offset, 0.0
    )
    w_curr = g.horizontal_reference_point(
        moved[0].normal, moved[0].offset, moved[1].normal, moved[1].offset, 0.0
    )
    np.testing.assert_allclose(w_curr, w_prev - t[:2], atol=1e-7)


@given(seeds)
def test_fit_plane_exact_on_noise_free_points(seed: int) -> None:
    rng = np.random.default_rng(seed)
    plane = random_plane(rng)
    n, d, s = g.fit_plane(points_on(plane, rng))
    if n @ plane.normal < 0:
        n, d = -n, -d
    np.testing.assert_allclose(n, plane.normal, atol=1e-9)
    assert d == pytest.approx(plane.offset, abs=1e-8)
    assert s[2] < 1e-8


def test_fit_plane_rejects_bad_input() -> None:
    with pytest.raises(GeometryError, match="at least 3"):
        g.fit_plane(np.zeros((2, 3)))
    with pytest.raises(GeometryError, match="NaN"):
        g.fit_plane(np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0.0]]))
    with pytest.raises(GeometryError, match="shape"):
        g.fit_plane(np.zeros((5, 2)))


def test_plane_validation_and_normalisation() -> None:
    p = g.Plane(np.array([0, 0, 2.0]), 4.0)
    np.testing.assert_allclose(p.coefficients, [0, 0, 1, 2])
    with pytest.raises(GeometryError, match="zero length"):
        g.Plane(np.zeros(3), 1.0)
    with pytest.raises(GeometryError, match="finite"):
        g.Plane(np.array([np.nan, 0, 1]), 1.0)
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


@given(seeds)
def test_pose_gtsam_round_trip_and_error(seed: int) -> None:
    rng = np.random.default_rng(seed)
    T = random_pose(rng)
    np.testing.assert_allclose(g.pose_from_gtsam(g.pose_to_gtsam(T)), T, atol=1e-12)
    assert g.pose_error(T, T) == pytest.approx((0.0, 0.0), abs=1e-7)
    dT = g.transform_from_rpy_xyz(0, 0, 0.01, 0.3, 0)
    rot, trans = g.pose_error(T @ dT, T)
    assert rot == pytest.approx(0.01) and trans == pytest.approx(0.3)


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


def test_plane_gtsam_round_trip_and_tangent_covariance() -> None:
    cov = np.diag([1e-4, 2e-4, 0.0, 4e-4])  # no variance along n = z
    p = g.Plane(np.array([0, 0, 1.0]), 2.0, covariance=cov)
    q = g.plane_from_gtsam(g.plane_to_gtsam(p))
    np.testing.assert_allclose(q.coefficients, p.coefficients)
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
