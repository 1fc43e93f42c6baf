"""A one-entry memo keyed by the identity of array arguments.

The streaming odometry extracts most epochs twice from the same :class:`planodom.scan.Scan`
(with the predicted twist, then with the epoch's own, :mod:`planodom.odometry.deskew`).
What an extraction derives from the scan's fields alone and not from the deskewed points
(input checks, the ring count, the order by ring, the sweep timing) is then the same in
both, and :func:`identity_memo` lets the second extraction reuse it.

The key is the identity of the array arguments (held by weak references, so a memo never
keeps a scan alive) and the value of the others. Scans are frozen and their arrays are
not changed in place anywhere in planodom; a caller that changes a scan's arrays in place
between two extractions must build a new :class:`~planodom.scan.Scan` (or arrays) for it.
Results are returned as they were computed the first time, so the memoised functions
return read-only arrays or immutable values.
"""

from __future__ import annotations

import functools
import weakref
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

F = TypeVar("F", bound=Callable[..., Any])


def key_part(arg: object) -> tuple[bool, object]:
    """A weak reference for an array (identity: True), else the value (hashable scalars,
    None: False)."""
    if isinstance(arg, np.ndarray):
        return (True, weakref.ref(arg))
    return (False, arg)


def same_args(parts: list[tuple[bool, Any]], args: tuple[object, ...]) -> bool:
    """Whether ``args`` are the call the key ``parts`` were made of: the very same arrays
    (alive), and values of the same type and equal (an array never equals a value)."""
    if len(parts) != len(args):
        return False
    for (is_array, ref), arg in zip(parts, args, strict=True):
        if is_array:
            held = ref()
            if held is None or held is not arg:
                return False
        elif type(arg) is not type(ref) or not ref == arg:  # values are never arrays
            return False
    return True


def identity_memo(fn: F) -> F:
    """``fn`` remembering its last call: called again with the very same arrays (``is``)
    and equal other arguments (positional only), it returns the last result."""
    last: list[Any] = [None, None]  # [key parts, result]

    @functools.wraps(fn)
    def wrapper(*args: object) -> Any:
        parts = last[0]
        if parts is not None and same_args(parts, args):
            return last[1]
        result = fn(*args)
        last[0], last[1] = [key_part(a) for a in args], result
        return result

    return wrapper  # type: ignore[return-value]


def read_only(a: np.ndarray) -> np.ndarray:
    """``a`` marked read-only (in place) and returned: a memoised result is shared."""
    a.flags.writeable = False
    return a


def float64_c(a: np.ndarray) -> np.ndarray:
    """``a`` (any shape) as a C-contiguous float64 array: ``a`` itself when it is one, else
    ``np.ascontiguousarray(a, dtype=np.float64)``. For an array numba allocated (the
    deskewed points) numpy's call returns a new view each time even when nothing needs
    converting (its dtype object is another, equal one), so a memo keyed on identity
    (:func:`identity_memo`) downstream missed every time (measured: the RANSAC agreement
    check recomputed the range image's grid and pixel normals on every deskewed scan)."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous:
        return a
    return np.ascontiguousarray(a, dtype=np.float64)
