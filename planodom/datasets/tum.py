"""Trajectories in the TUM format: ``time tx ty tz qx qy qz qw`` per line.

Each line is ``T_world_base`` at ``time`` (seconds): translation in metres, unit
quaternion in (x, y, z, w) order; blank lines and ``#`` comments are skipped. The format
is the one of ``evo.tools.file_interface`` (files written here read identically there).

Reading is done here rather than with evo's ``read_tum_trajectory_file`` because that one
reports a bad file without its line, checks only the first row's length and accepts
non-unit quaternions. evo's writer is exact (``np.savetxt`` with ``%.18e``); the writer
here is exact too (each value as Python's ``repr``, the shortest decimal that parses back
to the same float64) and easier to read, and adds a header comment.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.errors import DatasetError

#: Largest accepted deviation of a quaternion's norm from 1 (files written with 6 decimals
#: are off by ~1e-6); within it quaternions are normalised.
QUATERNION_NORM_TOL = 1e-3
#: Largest position magnitude (m): UTM northings (1e7 m) and ECEF positions fit; beyond it
#: squared errors lose all precision and overflow (a 1e300 gives ATE inf).
MAX_POSITION_M = 1e8
#: Largest time magnitude (s): TUM times are seconds (nanosecond stamps, 1e18, are not).
MAX_TIME_S = 1e11


def read_tum(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory file.

    Returns:
        times (E,) float64 seconds, strictly increasing, and poses (E, 4, 4) float64
        ``T_world_base``; positions are bit-exact to the file's decimal values.

    Raises:
        DatasetError: naming ``path`` (and ``path:line`` for a bad line) when the file is
            missing, empty, has a line that is not 8 finite numbers, a quaternion whose norm
            is not 1, or times that do not increase.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: trajectory file does not exist")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read trajectory file ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not a trajectory file (not UTF-8 text)") from None
    rows: list[list[float]] = []
    line_numbers: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        tokens = stripped.split()
        try:
            values = [float(tok) for tok in tokens]
        except ValueError:
            values = []
        if len(tokens) != 8 or len(values) != 8 or not np.all(np.isfinite(values)):
            raise DatasetError(
                f"{path}:{number}: expected 8 finite numbers 'time tx ty tz qx qy qz qw', "
                f"got {stripped[:80]!r}{_hint(stripped, not rows)}"
            )
        rows.append(values)
        line_numbers.append(number)
    if not rows:
        raise DatasetError(f"{path}: no poses in the trajectory file")
    table = np.array(rows)
    lines = np.array(line_numbers)
    times, xyz, quat = table[:, 0], table[:, 1:4], table[:, 4:8]
    for column, limit, what in (
        (times, MAX_TIME_S, "time (s)"),
        (xyz, MAX_POSITION_M, "position (m)"),
    ):
        far = np.flatnonzero(np.abs(column.reshape(len(table), -1)).max(axis=1) > limit)
        if far.size:
            raise DatasetError(
                f"{path}:{lines[far[0]]}: {what} beyond {limit:g} ({far.size} such lines)"
            )

    with np.errstate(over="ignore"):  # 1e300: inf, refused below
        norm = np.linalg.norm(quat, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > QUATERNION_NORM_TOL)
    if bad.size:
        raise DatasetError(
            f"{path}:{lines[bad[0]]}: quaternion norm {norm[bad[0]]:.6g} is not 1 "
            f"({bad.size} such lines)"
        )
    back = np.flatnonzero(np.diff(times) <= 0)
    if back.size:
        raise DatasetError(
            f"{path}:{lines[back[0] + 1]}: time {float(times[back[0] + 1])!r} does not "
            f"increase (previous {float(times[back[0]])!r})"
        )
    poses = np.tile(np.eye(4), (len(times), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(quat / norm[:, None]).as_matrix()
    poses[:, :3, 3] = xyz
    return times, poses


def _hint(line: str, first: bool) -> str:
    """What a bad line looks like: values separated by commas, or a header line."""
    if "," in line:
        return " (values separated by commas: a TUM file separates them by spaces)"
    if first and not any(c.isdigit() for c in line):
        return " (a header line? a TUM file's comments start with '#')"
    return ""


def write_tum(path: str | Path, times: np.ndarray, poses: np.ndarray) -> None:
    """Write times (E,) seconds and poses (E, 4, 4) ``T_world_base`` as a TUM file.

    Times and positions round-trip bit-exactly through :func:`read_tum`; rotations to
    ~1e-16 (the matrix-quaternion conversion). Rotation parts are taken as rotations
    (nearest rotation for slightly non-orthonormal ones).
    """
    path = Path(path)
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    poses = np.asarray(poses, dtype=np.float64)
    if poses.shape != (len(times), 4, 4):
        raise DatasetError(
            f"{path}: expected poses of shape ({len(times)}, 4, 4) for {len(times)} times, "
            f"got {poses.shape}"
        )
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(poses))):
        raise DatasetError(f"{path}: times or poses are not finite")
    quat = Rotation.from_matrix(poses[:, :3, :3]).as_quat(canonical=True)  # (x, y, z, w)
    table = np.column_stack([times, poses[:, :3, 3], quat])
    # repr is the shortest decimal that parses back to the same float64.
    lines = [" ".join(repr(v) for v in row.tolist()) for row in table]
    path.write_text("# time tx ty tz qx qy qz qw\n" + "".join(ln + "\n" for ln in lines))
