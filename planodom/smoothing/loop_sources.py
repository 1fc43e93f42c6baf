"""Loop factors that share their older epoch's planes (``smoothing.sandwich_loop_sources``).

A loop factor is a relative pose between two epochs more than ``smoothing.delta_max``
apart, solved from the planes of both. Its covariance is the solver's, and the graph takes
every loop factor as independent of the others. But the loop factors from one older epoch
(the lap's end closing on its first epochs: 16 factors from epoch 0 on 2D-rig world 148 at
2 cm) are all solved from that epoch's same planes, so the part of their errors that those
planes make is one error, shared, which does not average out over the factors. From the
first epoch, the gauge, it moves the whole lap: on worlds 144 and 148 at 2 cm the loop
factors from epoch 0 alone make the lap's one rotation against its first pose (0.7 and 0.8
mrad in yaw) and the mean NEES5 (16.4 and 19.0; 1.9 and 1.4 without their response,
``experiments/nees_classes.py``).

"shared" models that: each loop factor's whitened error gets, besides its own noise, a
part ``sqrt(share) u_a`` (``u_a`` standard normal, one per older epoch ``a``, the same for
every loop factor from ``a``) in the sandwich's ``S`` (:mod:`.sandwich`): half its
covariance by default, the older epoch's planes' half of a relative pose solved from two
epochs' planes alike. Whitened alike, loop factors from one epoch with similar covariances
then share that part whole. "deskew" sizes the shared part instead by the older epoch's
deskewing error through each factor's Jacobian, in that epoch's own column
(:mod:`.loop_deskew`). Only the covariances change.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import gtsam
import numpy as np

from planodom.geometry import Plane
from planodom.smoothing.loop_deskew import loop_deskew_maps
from planodom.smoothing.loop_records import LoopFactor

#: The share of a loop factor's covariance its older epoch's planes make (two epochs'
#: planes alike: half).
SHARE = 0.5


def loop_source_maps(
    graph: gtsam.NonlinearFactorGraph, n_epochs: int, delta_max: int, share: float = SHARE
) -> tuple[dict[int, tuple[int, np.ndarray]], np.ndarray]:
    """Error maps of ``graph``'s loop factors (two pose keys ``X(a)``, ``X(b)``, ``b - a``
    beyond ``delta_max``, a Gaussian noise model: not a robust outlier) for the sandwich:
    factor index -> (column ``n_epochs + j``, one per older epoch ``a``; (m, 6)
    ``sqrt(share) [I_m 0]``), and (J, 6, 6) the columns' covariances (identity)."""
    columns: dict[int, int] = {}
    maps: dict[int, tuple[int, np.ndarray]] = {}
    for i in range(graph.size()):
        factor = graph.at(i)
        if factor is None or len(factor.keys()) != 2:
            continue
        symbols = [gtsam.Symbol(key) for key in factor.keys()]
        if any(chr(s.chr()) != "x" for s in symbols) or factor.dim() > 6:
            continue
        a, b = sorted(int(s.index()) for s in symbols)
        noise = factor.noiseModel()  # type: ignore[attr-defined]  # a NoiseModelFactor
        if b - a <= delta_max or not isinstance(noise, gtsam.noiseModel.Gaussian):
            continue
        column = columns.setdefault(a, n_epochs + len(columns))
        g = np.zeros((factor.dim(), 6))
        g[:, : factor.dim()] = np.sqrt(share) * np.eye(factor.dim())
        maps[i] = (column, g)
    return maps, np.tile(np.eye(6), (len(columns), 1, 1))


def loop_error_maps(
    mode: str,
    cov_graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    motion_change: np.ndarray,
    delta_max: int,
    index: Mapping[int, int],
    loops: tuple[Sequence[LoopFactor], Mapping[int, Sequence[Plane]]],
) -> tuple[dict[int, tuple[int, np.ndarray]], np.ndarray] | None:
    """The sandwich's ``extra`` error maps for ``smoothing.sandwich_loop_sources`` ``mode``:
    None for "independent", :func:`loop_source_maps` for "shared", for "deskew"
    :func:`.loop_deskew.loop_deskew_maps` (``loops``: the builder's loop factors and
    planes per epoch; ``index``: whole graph -> ``cov_graph``) in the epochs' own columns
    of ``motion_change`` (E, 6, 6), no new column."""
    if mode == "shared":
        return loop_source_maps(cov_graph, len(motion_change), delta_max)
    if mode == "deskew":
        maps = loop_deskew_maps(cov_graph, values, loops[0], index, loops[1], motion_change)
        return maps, np.zeros((0, 6, 6))
    return None
