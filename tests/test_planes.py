"""PlaneSet: the arrays of a plane list, and its conversions against Plane."""

from __future__ import annotations

import numpy as np
from planes_factory import observe, world_planes

from planodom.geometry import Plane, transform_from_rpy_xyz
from planodom.planes import PlaneSet, as_plane_set


def planes(seed: int = 1) -> list[Plane]:
    rng = np.random.default_rng(seed)
    return observe(world_planes(rng, 5), transform_from_rpy_xyz(0.02, -0.01, 0.4, 1.0, 2.0, 0))


def test_from_planes_keeps_order_values_and_unknowns():
    ps = planes()
    arr = PlaneSet.from_planes(ps)
    assert len(arr) == len(ps)
    np.testing.assert_array_equal(arr.coefficients, np.stack([p.coefficients for p in ps]))
    assert np.all(arr.radii > 0)
    bare = PlaneSet.from_planes([Plane([0, 0, 1.0], 1.0)])
    assert np.isnan(bare.radii[0]) and np.isnan(bare.centroids[0]).all()
    assert np.isnan(bare.covariances).all() and bare.weights[0] == 1.0
    assert as_plane_set(arr) is arr and len(as_plane_set([])) == 0
    # radii: the farthest polygon vertex from the centroid, plane by plane, a bare plane
    # among them (no support) keeping NaN
    mixed = PlaneSet.from_planes([ps[0], Plane([0, 0, 1.0], 1.0), *ps[1:]])
    for i, p in enumerate(ps):
        far = np.max(np.linalg.norm(p.support.polygon - p.support.centroid, axis=1))
        assert mixed.radii[i + (i > 0)] == far
    assert np.isnan(mixed.radii[1]) and mixed.covariances.shape == (len(ps) + 1, 4, 4)


def test_transformed_agrees_with_plane_transformed():
    ps = [
        Plane(p.normal, p.offset, covariance=np.diag([1e-4, 2e-4, 3e-4, 1e-3]), support=p.support)
        for p in planes(2)
    ]
    T = transform_from_rpy_xyz(0.1, -0.2, 0.7, 3.0, -1.0, 0.5)
    moved = PlaneSet.from_planes(ps).transformed(T)
    one_by_one = PlaneSet.from_planes([p.transformed(T) for p in ps])
    np.testing.assert_allclose(moved.coefficients, one_by_one.coefficients, atol=1e-12)
    np.testing.assert_allclose(moved.covariances, one_by_one.covariances, atol=1e-15)
    np.testing.assert_allclose(moved.centroids, one_by_one.centroids, atol=1e-12)
    # A point on each plane stays on it: n . (T p) + d = 0.
    on_plane = -ps[0].offset * ps[0].normal
    p_a = T[:3, :3] @ on_plane + T[:3, 3]
    assert abs(moved.normals[0] @ p_a + moved.offsets[0]) < 1e-12


def test_take_selects_rows_in_order():
    arr = PlaneSet.from_planes(planes(3))
    sub = arr.take(np.array([2, 0]))
    np.testing.assert_array_equal(sub.normals, arr.normals[[2, 0]])
    np.testing.assert_array_equal(sub.covariances, arr.covariances[[2, 0]])
