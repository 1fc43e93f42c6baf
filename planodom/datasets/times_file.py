"""A dataset's ``times.txt``: one epoch time in seconds a line (read, written, and
compared with ``poses.tum``'s times when both are there)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planodom.datasets.tum import MAX_TIME_S
from planodom.errors import DatasetError


def read_times(path: str | Path, n_epochs: int) -> np.ndarray:
    """(E,) epoch times, seconds, from a ``times.txt`` (one number per line).

    Raises:
        DatasetError: naming ``path:line`` for a line that is not one finite number
            within ``MAX_TIME_S`` (of ``poses.tum``), or the file when the count is not
            ``n_epochs`` or the times do not increase.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: cannot read epoch times ({exc})") from None
    times = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            value = float(line)
        except ValueError:
            value = float("nan")
        if not np.isfinite(value):
            raise DatasetError(f"{path}:{number}: expected one finite time in seconds")
        if abs(value) > MAX_TIME_S:  # as poses.tum: read as seconds, ns were 1.7e18 s
            raise DatasetError(
                f"{path}:{number}: time {value:g} s is beyond {MAX_TIME_S:g} s "
                f"({unix_unit(value)}? the times are seconds)"
            )
        times.append(value)
    out = np.array(times, dtype=np.float64)
    if len(out) != n_epochs:
        raise DatasetError(f"{path}: {len(out)} times for {n_epochs} scan files")
    if np.any(np.diff(out) <= 0):
        k = int(np.flatnonzero(np.diff(out) <= 0)[0])
        raise DatasetError(f"{path}: times must increase (epoch {k + 1} is not after {k})")
    return out


def unread_times(path: Path, times: np.ndarray, poses_file: str) -> str | None:
    """The note on a ``times.txt`` beside ``poses_file`` (whose ``times`` (E,) s are the
    epochs') that gives other times (beyond 1 us), or cannot be read as the epochs' times;
    None when they agree."""
    try:
        off = float(np.max(np.abs(read_times(path, len(times)) - times)))
    except DatasetError as exc:
        off, why = np.inf, f" ({exc})"
    if off <= 1e-6:
        return None
    why = f": the two differ by up to {off:.6g} s" if np.isfinite(off) else why
    return f"{path}: not read, {poses_file} beside it gives the epoch times{why}"


def write_times(path: str | Path, times: np.ndarray) -> None:
    """Write epoch times (E,) seconds to a ``times.txt``, exact (``repr``) decimals."""
    lines = [repr(float(t)) for t in np.asarray(times, dtype=np.float64).reshape(-1)]
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


#: The longest epoch period a scanner gives, s: lidars sweep at 5 to 20 Hz, 2D scanners at
#: 10 to 100 Hz, the slowest nodding or turning 2D scanners in about 2 s; a median spacing
#: of five times that is no sweep (a judgement from sensor rates, not fitted to data).
SLOWEST_PERIOD_S = 10.0


def epoch_unit_note(times: np.ndarray, source: str) -> str | None:
    """A note when the epoch times (E,) s lie further apart (median) than
    :data:`SLOWEST_PERIOD_S`: times written in ms, µs or ns from the start read as seconds
    (0, 100, 200 ms read as 100 s apart: the simulated paper loop's poses 1.7 m off, no
    word); names the unit that makes the spacing a sweep's (5 ms to 2 s) when one does."""
    if len(times) < 2:
        return None
    period = float(np.median(np.diff(times)))
    if not period > SLOWEST_PERIOD_S:
        return None
    units = (("milliseconds", 1e-3), ("microseconds", 1e-6), ("nanoseconds", 1e-9))
    fits = [unit for unit, scale in units if 0.005 <= period * scale <= 2.0]
    guess = f"{fits[0]}? " if len(fits) == 1 else ""
    return (
        f"{source}: the epochs lie {period:.3g} s apart (median), where a scanner sweeps in "
        f"{SLOWEST_PERIOD_S / 5:g} s or less: {guess}the epoch times are read as seconds; read "
        "as given, the motion between epochs is spread over that time (the motion "
        "prediction and the deskewing follow it)"
    )


def unix_unit(value: float) -> str:
    """The unit in which ``value`` is a Unix time of this era (1e9 to 4.2e9 s; 1.7e12 is
    milliseconds), "nanoseconds" when none is."""
    for unit, scale in (("milliseconds", 1e3), ("microseconds", 1e6), ("nanoseconds", 1e9)):
        if 1e9 <= abs(value) / scale <= 4.2e9:
            return unit
    return "nanoseconds"
