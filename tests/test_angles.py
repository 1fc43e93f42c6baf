"""The remembered configuration values (planodom.angles) equal numpy's, bit for bit."""

import numpy as np
import pytest

from planodom import angles


@pytest.mark.parametrize("deg", [0.0, 0.5, 3.0, 10.0, 30.0, 45.0, 89.9])
def test_remembered_values_are_numpys(deg: float) -> None:
    assert angles.radians(deg) == np.radians(deg)
    assert angles.cos_of_degrees(deg) == float(np.cos(np.radians(deg)))
    assert angles.sin_of_degrees(deg) == float(np.sin(np.radians(deg)))
    again = angles.radians(deg)
    assert again == np.radians(deg)  # from the cache now


def test_pose_floor_is_the_diagonal_and_read_only() -> None:
    floor = angles.pose_floor(0.01, 0.002)
    r2 = np.radians(0.01) ** 2
    np.testing.assert_array_equal(floor, np.diag([r2, r2, r2, 0.002**2, 0.002**2]))
    with pytest.raises(ValueError):
        floor[0, 0] = 1.0  # shared between calls: never written
    cov = np.eye(5)
    assert (cov + floor)[3, 3] == 1.0 + 0.002**2
