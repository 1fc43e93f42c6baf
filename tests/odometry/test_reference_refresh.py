"""Extracting a never-deskewed reference epoch again with the next epoch's twist
(:meth:`planodom.odometry.odometry.PlaneOdometry._refresh_reference`,
``odometry.reference_refresh_guard``)."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry, Status
from planodom.scan import Scan


def trajectory(n: int, seed: int):
    """World planes and n poses of a vehicle driving a gentle curve."""
    world = world_planes(np.random.default_rng(seed), 10)
    poses = [
        transform_from_rpy_xyz(0.0, 0.0, 0.03 * k, 0.1 * k, 0.002 * k**2, 0.0) for k in range(n)
    ]
    return world, poses


@pytest.mark.parametrize("guard", [True, False])
def test_a_reference_that_loses_its_planes_with_the_next_twist_keeps_them(guard):
    """Epoch 0 is extracted without a twist (the first); once epoch 1 is estimated, epoch 0
    is extracted again with epoch 1's twist. Here that extraction finds only the first
    plane (the twist does not fit epoch 0), and epoch 1 against it is unresolved: with the
    guard epoch 0's planes are brought back and epoch 1 keeps its exact estimate against
    them; without it epoch 1 stays unresolved against the one plane."""
    world, poses = trajectory(3, seed=5)
    planes = [observe(world, T) for T in poses]
    calls: list[tuple[int, bool]] = []

    def extractor(scan, cfg, twist=None):
        k = int(scan.points[0, 0])
        calls.append((k, twist is not None))
        return planes[k][:1] if (k == 0 and twist is not None) else planes[k]

    odo = PlaneOdometry(
        PlanodomConfig().updated(
            {
                "odometry.pipeline": "wocsc",
                "odometry.reference_refresh_guard": guard,
                "odometry.start_refresh": False,  # the policy's own refresh alone
            }
        ),
        extractor=extractor,
    )
    for k in range(3):
        odo.register_epoch(Scan(np.full((2, 3), float(k)), t=[0.0, 0.05]), 0.1 * k)
    assert (0, True) in calls  # the reference was extracted again with a twist
    assert calls.count((0, True)) == 1  # and only once
    truth = invert_transform(poses[0]) @ poses[1]
    if guard:
        assert len(odo.planes[0]) == len(planes[0])
        assert odo.results[1].status is Status.OK
        np.testing.assert_allclose(odo.poses[1], truth, atol=1e-9)
    else:
        assert len(odo.planes[0]) == 1
        assert odo.results[1].status is Status.UNRESOLVED
