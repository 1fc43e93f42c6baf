"""A reference trajectory whose quaternions were written ``qw qx qy qz`` (EuRoC's, Eigen's
``coeffs`` printed by hand, many CSV exports) where TUM has ``qx qy qz qw``.

Such a file reads as valid unit quaternions, and ``planodom eval`` scored a perfect
estimate against it at 1.6 m ATE and 0.85 deg RPE (the simulated paper loop's 60 epochs):
no error, no word. The orientations cannot be judged alone, but against the estimate they
can: two trajectories of one body differ by a constant rotation of their world frames,
``R_ref_k R_est_k^T``, whatever the motion; read in the wrong order that offset turns as
the vehicle turns (a yaw about z read as a roll about x), so the reading with the constant
offset is the file's.
"""

from __future__ import annotations

import numpy as np

#: The other reading's offset must vary this many times less than TUM's own before a note:
#: a judgement, not fitted (a misread rotation turns the offset with the heading, by tens
#: of degrees over a drive with turns; an estimate's drift by a few).
BETTER_BY = 10.0
#: ... and TUM's own reading's offset must vary by more than this (rad; 2 deg): on a
#: straight drive both readings give a near-constant offset and nothing is said.
VARIES_RAD = np.radians(2.0)


def offset_spread(est_poses: np.ndarray, ref_poses: np.ndarray) -> float:
    """The median angle (rad) of ``R_ref_k R_est_k^T`` from its mean over the poses: the
    world frames' offset, constant when both are poses of one body, whatever the drift of
    the estimate's rotation (which adds to it slowly)."""
    from scipy.spatial.transform import Rotation

    offsets = Rotation.from_matrix(
        ref_poses[:, :3, :3] @ np.transpose(est_poses[:, :3, :3], (0, 2, 1))
    )
    mean = offsets.mean()
    return float(np.median((mean.inv() * offsets).magnitude()))


def reordered(poses: np.ndarray) -> np.ndarray:
    """``poses`` (E, 4, 4) with each rotation's quaternion read again as if its
    ``x y z w`` had been written ``w x y z`` (the positions kept)."""
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_matrix(poses[:, :3, :3]).as_quat()  # as the file was read
    out = poses.copy()
    out[:, :3, :3] = Rotation.from_quat(xyzw[:, [1, 2, 3, 0]]).as_matrix()
    return out


def wxyz_note(est_poses: np.ndarray, ref_poses: np.ndarray, ref_name: str) -> str | None:
    """A note when the matched reference poses (E, 4, 4) agree with the estimate's
    (E, 4, 4) only with their quaternions read in ``w x y z`` order; None otherwise."""
    if len(est_poses) < 3:
        return None
    as_read = offset_spread(est_poses, ref_poses)
    other = offset_spread(est_poses, reordered(ref_poses))
    if as_read <= VARIES_RAD or other * BETTER_BY > as_read:
        return None
    return (
        f"{ref_name}: its orientations agree with the estimate's only when its quaternions "
        f"are read as qw qx qy qz (their offset from the estimate's varies by "
        f"{np.degrees(as_read):.3g} deg as read, {np.degrees(other):.2g} deg so): TUM's "
        "order is qx qy qz qw; the rotation errors and the alignment are wrong unless the "
        "file is rewritten"
    )
