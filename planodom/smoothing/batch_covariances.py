"""The batch's pose covariances: fitted (the graph's information, optionally reweighted by
its variance components) or sandwich (:mod:`.sandwich`), chosen by
``smoothing.covariance_model`` ("auto": the sandwich where its inputs exist)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import gtsam
import numpy as np
from scipy.stats import chi2

from planodom.config import SmoothingConfig
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing.deskew_epoch import epoch_sizes
from planodom.smoothing.deskew_scale import scaled_motion_change
from planodom.smoothing.first_epoch_noise import with_first_step
from planodom.smoothing.graph import GraphBuilder
from planodom.smoothing.marginals import pose_covariances
from planodom.smoothing.sandwich import batch_sandwich, deskew_motion_change
from planodom.smoothing.undeskewed import with_undeskewed
from planodom.smoothing.unmeasured import with_unmeasured
from planodom.smoothing.variance_components import VarianceComponents, factor_groups, scale_noise

NO_JACOBIANS = (
    "fitted covariances: no plane factor carries its deskewing Jacobian "
    "(extraction.deskew_jacobian), which the sandwich covariances need"
)


def covariance_graph(
    graph: gtsam.NonlinearFactorGraph,
    gaussian: Mapping[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
    inlier_quantile: float | None,
) -> gtsam.NonlinearFactorGraph:
    """The graph whose linearisation gives the batch covariances.

    A robust factor (index ``i`` in ``graph``, Gaussian twin ``gaussian[i]``) whose
    squared whitened error at ``values`` lies within the ``inlier_quantile`` of chi2(its
    dimension) is an inlier: its Gaussian twin is used, with full weight. Others keep the
    robust kernel's weight. Without this the kernel's weights on inliers make the
    covariances cautious: a Cauchy kernel (2.38 sigma) weighs a 3-dim factor with a
    typical error (norm sqrt(3)) by 0.65, so the poses' covariances grow by about 1.5;
    the estimate itself is the robust one. None: ``graph`` as it is.
    """
    if inlier_quantile is None or not gaussian:
        return graph
    out = gtsam.NonlinearFactorGraph()
    limits: dict[int, float] = {}  # dimension -> chi2 quantile (scipy's ppf is slow)
    for i in range(graph.size()):
        twin = gaussian.get(i)
        if graph.at(i) is None:  # removed (a re-identification refused by the gate)
            continue
        if twin is not None and twin.dim() not in limits:
            limits[twin.dim()] = float(chi2.ppf(inlier_quantile, twin.dim()))
        if twin is not None and 2.0 * twin.error(values) <= limits[twin.dim()]:
            out.add(twin)
        else:
            out.add(graph.at(i))
    return out


def sandwich_inputs(
    cfg: SmoothingConfig,
    planes: Mapping[int, tuple[int, Plane]],
    relative_poses: Sequence[RelativePose],
    n_epochs: int,
) -> tuple[np.ndarray | None, str | None]:
    """The epochs' (E, 6, 6) changes of motion the sandwich takes as each epoch's
    deskewing error (:func:`.sandwich.deskew_motion_change`, scaled per run with
    ``sandwich_motion_scale`` "run", or sized per epoch with "epoch",
    :mod:`.deskew_epoch`; with ``sandwich_undeskewed`` "motion" the epochs kept
    without deskewing also the motion over their points, :mod:`.undeskewed`, with
    ``sandwich_unmeasured`` "motion" the epochs no step into was measured,
    :mod:`.unmeasured`; with
    ``sandwich_first_epoch`` the first epoch also its first step's error,
    :mod:`.first_epoch_noise`), or None for
    the fitted covariances, and a note why when ``covariance_model`` "auto" falls back
    although the epochs are spread in time.

    "sandwich": always the changes (zero for epochs taken at one instant). "auto": None
    with ``deskew_noise`` or ``covariance_scale`` other than "none" (those change the noise
    models themselves), where no epoch has a change of motion (scans taken at one instant:
    the sandwich equals the fitted covariances), or where no plane factor carries its
    ``Plane.deskew_jacobian`` (then with :data:`NO_JACOBIANS`)."""
    model = cfg.covariance_model
    if model == "fitted":
        return None, None
    if model == "auto" and (cfg.deskew_noise != "none" or cfg.covariance_scale != "none"):
        return None, None
    Q = deskew_motion_change(relative_poses, n_epochs)
    if cfg.sandwich_motion_scale != "none":
        Q = scaled_motion_change(Q, relative_poses)[0]
    if cfg.sandwich_motion_scale == "epoch":
        Q = epoch_sizes(Q, planes, relative_poses)
    if cfg.sandwich_undeskewed == "motion":
        Q = with_undeskewed(Q, relative_poses)
    if cfg.sandwich_unmeasured == "motion":
        Q = with_unmeasured(Q, relative_poses)
    if cfg.sandwich_first_epoch != "motion":
        Q = with_first_step(Q, relative_poses, cfg.sandwich_first_epoch == "degenerate_step")
    if model == "sandwich":
        return Q, None
    if not np.any(Q):
        return None, None
    if not any(plane.deskew_jacobian is not None for _, plane in planes.values()):
        return None, NO_JACOBIANS
    return Q, None


def batch_covariances(
    builder: GraphBuilder,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    fallback: list[int],
    estimate: gtsam.Values,
    n_epochs: int,
    planes: Mapping[int, tuple[int, Plane]] | None = None,
    relative_poses: Sequence[RelativePose] = (),
) -> tuple[gtsam.Values, np.ndarray | None, str | None, VarianceComponents | None, str]:
    """The poses' marginal covariances at ``estimate`` (:func:`covariance_graph`), from
    the graph reweighted by its variance components with ``smoothing.covariance_scale``
    (then also the estimate it was resolved to), or the sandwich covariances
    (:func:`sandwich_inputs`; ``planes``: the plane factors' epochs and planes,
    ``relative_poses``: the run's, for the changes of motion; where no epoch has one,
    e.g. scans taken at one instant, the fitted ones as they are); a note instead when
    gtsam finds the system indeterminant. Returns (estimate, covariances, note,
    components, model): ``model`` "sandwich" or "fitted", the covariances computed."""
    cfg = builder.config
    cov_graph = covariance_graph(graph, gaussian, estimate, cfg.covariance_inlier_quantile)
    linear, components = None, None
    Q, why = sandwich_inputs(cfg, planes or {}, relative_poses, n_epochs)
    if builder.plane_share is not None:  # sandwich_plane_share "own": the same Q as the planes'
        Q = builder.plane_share
    if Q is not None and np.any(Q):  # (no change of motion, e.g. snapshot scans: fitted)
        try:
            sources = (getattr(builder, "loop_factors", ()), builder.planes)
            covariances, note = batch_sandwich(
                cfg, graph, cov_graph, planes or {}, Q, estimate, sources,
                (relative_poses, fallback),
            )  # fmt: skip
        except np.linalg.LinAlgError as exc:
            note = "sandwich covariances unavailable: " + " ".join(str(exc).split()[:14])
            return estimate, None, note, None, "sandwich"
        return estimate, covariances, note, None, "sandwich"
    try:
        if cfg.covariance_scale != "none":
            loops = [f.factor for f in getattr(builder, "loop_factors", ())]
            labels = factor_groups(
                graph, gaussian, estimate, loops, fallback, cfg.covariance_inlier_quantile
            )
            resolve = cfg.covariance_scale_estimate == "resolve"
            estimate, linear, components = scale_noise(
                cov_graph, labels, estimate, cfg.covariance_scale, resolve
            )
        covariances, note = pose_covariances(
            cov_graph, estimate, n_epochs, cfg.covariances_relative_to_first, cfg.prior_sigma,
            linear,
        )  # fmt: skip
    except (RuntimeError, np.linalg.LinAlgError) as exc:  # e.g. in the variance components
        note = "marginal covariances unavailable: " + " ".join(str(exc).split()[:14])
        return estimate, None, note, components, "fitted"
    if why is not None:
        note = why if note is None else f"{why}; {note}"
    return estimate, covariances, note, components, "fitted"
