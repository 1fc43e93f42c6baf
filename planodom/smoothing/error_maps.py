"""The sandwich's error maps (:mod:`.sandwich`): how a factor's whitened error changes with
the shared errors ``dxi_k`` (one column of ``S``'s root per epoch k, and the extra columns
after them).

``ErrorMaps``: index of a factor in the linearised graph -> one term ``(k, g)`` (column k,
``g`` (m, 6) the change of its whitened error with ``dxi_k``, m its dimension) or a
sequence of such terms (a relative-pose factor solved from two epochs' planes takes both
epochs' errors, :mod:`.relative_deskew`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import gtsam
import gtsam_unstable
import numpy as np

from planodom.geometry import Plane

ErrorMap = tuple[int, np.ndarray]
ErrorMaps = Mapping[int, ErrorMap | Sequence[ErrorMap]]

#: ``OrientedPlane3::errorVector``'s first-order change with the measured plane's tangent
#: coordinates ``delta`` (Unit3 basis (2), d) is ``sign * diag(1, 1, -1) delta`` at a
#: vanishing residual: +1 for the global factor, -1 for the anchored one (which takes the
#: difference the other way round; checked numerically in tests/smoothing/test_sandwich.py).
ERROR_SIGN = {gtsam.OrientedPlane3Factor: 1.0, gtsam_unstable.LocalOrientedPlane3Factor: -1.0}


def map_terms(error_maps: ErrorMaps, i: int) -> list[ErrorMap]:
    """The terms ``(k, g)`` of factor ``i`` in ``error_maps`` (none when it has no map)."""
    value = error_maps.get(i)
    if value is None:
        return []
    if isinstance(value[0], (int, np.integer)):
        return [value]  # type: ignore[list-item]  # one term
    return list(value)  # type: ignore[arg-type]  # a sequence of terms


def merged(*maps: ErrorMaps) -> dict[int, list[ErrorMap]]:
    """The error maps' terms per factor, all of them (a factor in several: its terms add)."""
    out: dict[int, list[ErrorMap]] = {}
    for m in maps:
        for i in m:
            out.setdefault(i, []).extend(map_terms(m, i))
    return out


def plane_error_map(factor: gtsam.NonlinearFactor, plane: Plane) -> np.ndarray | None:
    """(3, 6) first-order change of a plane factor's whitened error with its epoch's change
    of motion ``dxi`` (rotation (rad), translation (m) per epoch span), through the
    measured ``plane``'s ``deskew_jacobian`` (as oriented in the factor); None for a plane
    without it or a factor whose noise model is not Gaussian (a robust outlier)."""
    if plane.deskew_jacobian is None:
        return None
    sign = next((s for t, s in ERROR_SIGN.items() if isinstance(factor, t)), None)
    noise = factor.noiseModel()  # type: ignore[attr-defined]  # a NoiseModelFactor
    if sign is None or not isinstance(noise, gtsam.noiseModel.Gaussian):
        return None
    P = np.zeros((3, 4))  # (n, d) -> tangent, as plane_tangent_covariance
    P[:2, :3] = np.asarray(gtsam.Unit3(plane.normal).basis()).T
    P[2, 3] = 1.0
    tangent = P @ np.asarray(plane.deskew_jacobian, dtype=float)
    tangent[2] *= -1.0  # errorVector's offset part (planodom_factors.planes.plane_noise)
    return sign * np.asarray(noise.R()) @ tangent
