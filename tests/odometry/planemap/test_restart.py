"""Registering an epoch extracted again from the pose its earlier extraction found
(``planemap.restart``), on a synthetic row of walls where a prediction one wall spacing
off the truth is an alias of it."""

from __future__ import annotations

import numpy as np
import pytest
from planemap_factory import plane_points, planes_of, pose

from planodom.config import PlanodomConfig
from planodom.odometry import Status
from planodom.odometry.planemap import PlaneMapOdometry

#: Walls across the x axis, this far apart (m): a pose shifted by it along x sees them alike.
SPACING = 1.0
#: True steps: 0.2 m along x twice, then 0.8 m back (within the motion bounds; the constant
#: velocity predicts 0.2 m on: the prediction is SPACING off the truth, at an alias of it).
STEPS = [pose([0, 0, 0], [0.2, 0, 0]), pose([0, 0, 0], [0.2, 0, 0]), pose([0, 0, 0], [-0.8, 0, 0])]


def _row(T_world_base: np.ndarray, k: int) -> list:
    """Planes (scan frame) of the ground, two long side walls and walls across x every
    SPACING metres from -10 to 10 m, seen from ``T_world_base``."""
    rng = np.random.default_rng(90 + k)
    sets = [plane_points(rng, [0, 0, 1.0], 1.8, [0, 0, -1.8], 50, 2000)]
    sets += [plane_points(rng, [0, 1.0, 0], 4.0, [0, -4, 0], 50, 2000)]
    sets += [plane_points(rng, [0, -1.0, 0], 4.0, [0, 4, 0], 50, 2000)]
    for x in np.arange(-10.0, 10.0 + 1e-9, SPACING):
        sets.append(plane_points(rng, [-1.0, 0, 0], float(x), [x, 0, 0], 0.8, 300))
    inv = np.linalg.inv(T_world_base)
    return planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets])


def _run_to_last(mode: str) -> tuple[PlaneMapOdometry, list, np.ndarray]:
    """The odometry after the first three epochs, the last epoch's planes and its truth."""
    odo = PlaneMapOdometry(PlanodomConfig().updated({"planemap.restart": mode}))
    truth = [np.eye(4)]
    for step in STEPS:
        truth.append(truth[-1] @ step)
    for k, T in enumerate(truth[:-1]):
        odo.commit(odo.estimate(_row(T, k)))
    return odo, _row(truth[-1], len(truth) - 1), truth[-1]


def test_the_prediction_one_spacing_off_registers_at_the_alias() -> None:
    """What the restart is for: from the prediction the last epoch registers at the alias
    SPACING off the truth, all but the walls at the row's end associated (not suspect)."""
    odo, planes, truth = _run_to_last("prediction")
    est = odo.estimate(planes)
    assert est.relative.status is Status.OK
    assert est.T[0, 3] - truth[0, 3] == pytest.approx(SPACING, abs=0.01)


@pytest.mark.parametrize("mode", ["from_previous", "rejected"])
def test_an_epoch_extracted_again_is_registered_from_the_pose_found_before(mode: str) -> None:
    """Given the pose an earlier extraction found (3 cm and 0.5 deg off the truth), the
    epoch registers at the truth, not at the prediction's alias; with ``prediction`` (the
    default) the start is not used."""
    odo, planes, truth = _run_to_last(mode)
    start = truth @ pose([0, 0, 0.5], [0.03, 0.0, 0])
    est = odo.estimate(planes, start=start)
    assert est.relative.status is Status.OK
    np.testing.assert_allclose(est.T[:3, 3], truth[:3, 3], atol=1e-3)
    odo_default, planes, truth = _run_to_last("prediction")
    est = odo_default.estimate(planes, start=start)
    assert est.T[0, 3] - truth[0, 3] == pytest.approx(SPACING, abs=0.01)
