"""The checks of what the smoothers are given (:func:`check_epochs`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.errors import GeometryError
from planodom.geometry import Plane, rotation_problem
from planodom.odometry.relative import RelativePose


def check_epochs(
    epochs_planes: Sequence[Sequence[Plane]],
    relative_poses: Sequence[RelativePose] = (),
    T_world_first: object = None,
    name: str = "smooth_batch",
) -> None:
    """GeometryError, naming ``name`` (the smoother), for:

    - no epochs (numpy's 'need at least one array to stack');
    - an epoch that is not a list of planes (an (E, 3) array was smoothed as planes of
      floats);
    - a relative pose whose epochs are not ``0 <= prev < curr`` (unset, -1, or reversed:
      silently left out of the graph before); one whose ``curr`` lies beyond the epochs
      given is left out (a prefix of a run may be smoothed with all its relative poses);
    - a ``T_world_first`` that is no rigid (4, 4) transform (a traceback deep in the
      graph, or an error about plane normals for NaN).
    """
    if len(epochs_planes) == 0:
        raise GeometryError(f"{name}: no epochs to smooth")
    for k, planes in enumerate(epochs_planes):
        bad = next((p for p in planes if not isinstance(p, Plane)), None)
        if bad is not None:
            raise GeometryError(
                f"{name}: epoch {k} holds a {type(bad).__name__}, not planodom.Plane "
                "objects (epochs_planes: one list of planes per epoch)"
            )
    for i, rel in enumerate(relative_poses):
        if not 0 <= rel.prev < rel.curr:
            raise GeometryError(
                f"{name}: relative pose {i} links epoch {rel.prev} to epoch {rel.curr}; "
                "needs 0 <= prev < curr (the epoch indices smoothing_relatives sets)"
            )
    if T_world_first is not None:
        T = np.asarray(T_world_first, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            problem: str | None = f"shape {T.shape}" if T.shape != (4, 4) else "not finite"
        elif not np.array_equal(T[3], [0.0, 0.0, 0.0, 1.0]):
            problem = "its last row is not 0 0 0 1"
        else:
            problem = rotation_problem(T[:3, :3])
        if problem is not None:
            raise GeometryError(f"{name}: T_world_first is no rigid (4, 4) transform ({problem})")
