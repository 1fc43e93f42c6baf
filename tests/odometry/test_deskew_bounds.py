"""A re-extraction whose step leaves the motion bounds ends the deskewing refinement
(``odometry.deskew_bounds_guard``, :func:`planodom.odometry.deskew.register_deskewed`)."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

from planodom.config import AssociationConfig, PlanodomConfig
from planodom.geometry import invert_transform, transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry
from planodom.odometry.deskew import beyond_bounds
from planodom.scan import Scan


@pytest.mark.parametrize(
    ("rpy_deg", "xyz", "beyond"),
    [
        ((0.0, 0.0, 19.9), (0.0, 0.0, 0.0), False),
        ((0.0, 0.0, 20.1), (0.0, 0.0, 0.0), True),
        ((12.0, 0.0, 12.0), (0.0, 0.0, 0.0), False),  # 16.9 deg about a tilted axis
        ((15.0, 0.0, 15.0), (0.0, 0.0, 0.0), True),  # 21.1 deg
        ((0.0, 0.0, 0.0), (0.6, 0.79, 0.0), False),  # 0.991 m
        ((0.0, 0.0, 0.0), (0.6, 0.81, 0.0), True),  # 1.008 m
    ],
)
def test_beyond_bounds_is_the_rotation_angle_or_the_translation_norm(rpy_deg, xyz, beyond):
    """Default bounds 20 deg and 1 m; each case's rotation angle is checked against its
    value computed independently (scipy's rotation magnitude)."""
    from scipy.spatial.transform import Rotation

    step = transform_from_rpy_xyz(*np.radians(rpy_deg), *xyz)
    angle = np.degrees(Rotation.from_matrix(step[:3, :3]).magnitude())
    expected = angle > 20.0 or np.linalg.norm(xyz) > 1.0
    assert expected == beyond
    assert beyond_bounds(step, AssociationConfig()) is beyond


@pytest.mark.parametrize("guard", [True, False])
def test_a_refined_step_beyond_the_bounds_keeps_the_estimate_it_came_from(guard):
    """Epoch 1 extracted without a twist gives its exact planes; extracted again with its
    own twist it gives planes seen 23 deg rolled (a wrong grouping, as on generalisation
    world 114 at 2 cm), and epoch 0, extracted again with that twist too, its exact planes.
    The association's bounds (20 deg and the 5 deg normal margin) let the rolled planes in;
    with the guard the refined 23 deg step (beyond the 20 deg bound) is not kept: epoch 1
    keeps its exact step and epoch 0 its first planes; without it the rolled step is kept."""
    world = world_planes(np.random.default_rng(7), 10)
    poses = [transform_from_rpy_xyz(0.0, 0.0, 0.03 * k, 0.1 * k, 0.0, 0.0) for k in range(2)]
    rolled = poses[1] @ transform_from_rpy_xyz(np.radians(23.0), 0.0, 0.0, 0.0, 0.0, 0.0)
    calls: list[tuple[int, bool]] = []

    def extractor(scan, cfg, twist=None):
        k = int(scan.points[0, 0])
        calls.append((k, twist is not None))
        if k == 1 and twist is not None:
            return observe(world, rolled)
        return observe(world, poses[k])

    odo = PlaneOdometry(
        PlanodomConfig().updated(
            {"odometry.pipeline": "wocsc", "odometry.deskew_bounds_guard": guard}
        ),
        extractor=extractor,
    )
    for k in range(2):
        odo.register_epoch(Scan(np.full((2, 3), float(k)), t=[0.0, 0.05]), 0.1 * k)
    assert (0, True) in calls and (1, True) in calls  # both extracted again with the twist
    truth = invert_transform(poses[0]) @ poses[1]
    if guard:
        np.testing.assert_allclose(odo.poses[1], truth, atol=1e-9)
        assert calls.count((1, True)) == 1  # the refinement ended there
    else:
        wrong = invert_transform(poses[0]) @ rolled
        np.testing.assert_allclose(odo.poses[1][:3, :3], wrong[:3, :3], atol=1e-6)
