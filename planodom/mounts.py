"""Sensor mounts checked for their distance from the base frame's origin.

An extrinsic or a sensor origin is a sensor's place on the vehicle, so it lies within the
vehicle: a few metres from its base frame's origin. One written in millimetres (a CAD
drawing's or a calibration tool's units: a lidar 1.8 m up read as 1.8 km) or taken from a
frame that is not the vehicle's (``--base-frame odom`` where a single ``/tf`` message made
the odometry frame look rigid) was read without a word: a dataset's normals oriented
towards a sensor kilometres away, a bag's points moved by the lever arm, every rotation
error multiplied by it.

The bounds are vehicle sizes, not fitted to any recording: the longest road vehicles
(Australia's road trains) are 53.5 m and mining haul trucks about 15 m, so no sensor of
a vehicle lies farther than about 50 m from an origin on it; beyond
:data:`MOUNT_LIMIT_M`, twice that, a mount is refused (a millimetre-written mount of any
sensor 0.1 m or more from the origin lands there). Beyond :data:`MOUNT_NOTE_M`, the
longest articulated lorry of EU rules (25.25 m) with its sensors at one end and the
origin at the other, a mount is read as given and noted.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from planodom.errors import DatasetError

#: Metres from the base frame's origin beyond which a sensor mount is refused.
MOUNT_LIMIT_M = 100.0
#: Metres from the base frame's origin beyond which a sensor mount is noted.
MOUNT_NOTE_M = 25.0


def check_mounts(mounts: Iterable[tuple[str, np.ndarray]], hint: str) -> list[str]:
    """The notes of mounts farther than :data:`MOUNT_NOTE_M` from the base frame's origin.

    Args:
        mounts: ``(where, translation (3,) m)`` per sensor mount, ``where`` naming the file
            and field (or the transform) it was read from.
        hint: what to check beside the units, for the message (e.g. the base frame).

    Raises:
        DatasetError: naming the first mount farther than :data:`MOUNT_LIMIT_M`.
    """
    notes: list[str] = []
    for where, translation in mounts:
        t = np.asarray(translation, dtype=np.float64).reshape(3)
        metres = float(np.linalg.norm(t))
        xyz = ", ".join(f"{v:.6g}" for v in t)
        if metres > MOUNT_LIMIT_M:
            raise DatasetError(
                f"{where}: translation ({xyz}) puts the sensor {metres:.4g} m from the base "
                f"frame's origin, farther than any vehicle is long (a sensor on one lies "
                f"within {MOUNT_LIMIT_M:g} m): written in millimetres? (planodom reads "
                f"metres){hint}"
            )
        if metres > MOUNT_NOTE_M and not notes:
            notes.append(
                f"{where}: translation ({xyz}) puts the sensor {metres:.4g} m from the base "
                f"frame's origin, farther than a sensor on a vehicle usually is (within "
                f"{MOUNT_NOTE_M:g} m): read as given; check its units (metres){hint}"
            )
    return notes
