"""Configuration of the batch covariances' noise scale (planodom.smoothing.variance_components)."""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

from planodom.config.batch_speed import BatchSpeedConfig
from planodom.errors import ConfigError


class CovarianceScaleConfig(BatchSpeedConfig):
    """The scale of the batch graph's noise models estimated from its own residuals
    (a part of :class:`~planodom.config.smoothing.SmoothingConfig`)."""

    covariance_scale: Literal["none", "posterior", "groups"] = "none"
    """Batch covariances: "none" the noise models as built; "posterior" one a posteriori
    variance factor of the measurements (relative poses, planes, loop factors: weighted
    squared residuals over their redundancy; the priors, vertical and fallback
    pseudo-observations and the robust outliers keep their weight) multiplies their
    covariances; "groups" one factor per group (relative poses, planes, loop factors:
    Foerstner's variance component estimation). The poses' covariances are then those of
    the reweighted graph (planodom.smoothing.variance_components).

    "none" by default: the residuals do not see the excess. Ten 2D-rig laps, batch with
    loops: the posterior factor is 0.63-1.01 at 6 mm and 0.71-1.17 at 2 cm; per group
    planes 0.81-1.2, relative poses 0.14-0.98, loop factors 0.18-1.07 (a relative pose or
    loop factor shares planes with the plane factors, so its residual is small), while
    the mean NEES5 is 58-5900 at 6 mm (no covariances on 4 laps then) and 8.4-955 at 2 cm
    (inside a run's [0.83, 12.8] on 1 of 16); with the factors 57-9200 / 7.2-1250
    (posterior) and 59-10200 / 7.5-1290 (groups), still 1 inside. The excess is an error
    a pose takes whole, which leaves no residual: on world 0 (6 mm) roll and pitch (13
    and 11 sigmas rms), as large from one epoch to the next as in total, each epoch's
    deskewing tilting all its planes alike; on world 2 the whole lap turned against its
    first pose (yaw 0.060 deg mean error, sigma 0.001 deg). With ``deskew_noise``
    "twist_change_jacobian" (which models that error; 6 mm, 8 of 10 inside) the factor is
    0.06-0.29: 3 of those 8 out (world 2 5.5 -> 44), world 4 without covariances (gtsam
    finds the reweighted system indeterminant). Built-in scenes (``planodom
    experiment consistency``, 200 epochs): snapshot paper-loop at 6 mm / 2 cm / 10 cm
    NEES5 1.94 / 2.25 / 2.20 -> 2.02 / 2.27 / 2.01 (posterior; the models are honest
    there and the factor stays near 1); continuous paper-loop 39 / 7.9 -> 51 / 7.9,
    urban-canyon 6 mm 17 -> 26."""
    covariance_model: Literal["auto", "fitted", "sandwich"] = "auto"
    """Batch covariances (the estimate is the same in all): "auto" (default) the sandwich
    where its inputs exist, else the fitted ones (:func:`.batch_covariances.sandwich_inputs`:
    fitted with ``deskew_noise`` or ``covariance_scale`` other than "none", for epochs taken
    at one instant, and, with a note, where no plane carries its deskewing Jacobian);
    "fitted" the inverse of the
    graph's information at the estimate, as if its noise models were the whole error;
    "sandwich" the misspecified-model covariance ``A^-1 (A + J^T S J) A^-1``
    (:mod:`planodom.smoothing.sandwich`): the whitened measurements' error is ``I + S``,
    ``S`` holding each epoch's deskewing error, one change of motion per epoch (its
    covariance :meth:`.DeskewNoise.plane_motion_change`, from the run's own changes of
    motion) shared by all the epoch's plane factors through their own
    ``Plane.deskew_jacobian`` (switched on in the extraction with this mode). Epochs taken
    at one instant (``RelativePose.time_spread`` False) have no such error: there it gives
    the fitted covariances. Needs ``deskew_noise`` "none" and ``covariance_scale`` "none"
    (those change the noise models themselves). "auto" by default (this release; the
    extraction's Jacobians leave the odometry bit-identical; continuous built-in scenes,
    200 epochs: mean NEES5 39 / 7.9 / 17 / 8.4 -> 4.5 / 1.8 / 4.4 / 4.2, all inside;
    docs/RESULTS.md "The sandwich covariances by default"). Earlier, on the ten 2D-rig
    laps (batch with loops, the same poses) the mean NEES5 is inside the 95 % interval on
    6 of 10 runs at 6 mm (fitted 0; median 203 -> 1.02) and 4 of 10 at 2 cm (median 108 ->
    1.07), but too
    cautious on 8 of the 20 (down to 0.11: the batch's coplanar deskewing errs far less than
    the change of motion taken as its error) and 5-17 times the fitted covariances' time in
    median (dense in the poses; docs/RESULTS.md). With ``sandwich_motion_scale`` "run"
    (this release) inside on 14 of 18 (world 4 not run), none too cautious, 4 above."""
    sandwich_motion_scale: Literal["none", "run", "epoch"] = "run"
    """With ``covariance_model`` "sandwich": "none" each epoch's deskewing error has the
    covariance of the run's changes of motion around it; "run" that covariance scaled per
    axis by one factor each, estimated from the run by the method of moments (the twists
    the epochs were deskewed with against the odometry's steps over their points' times;
    :mod:`planodom.smoothing.deskew_scale`; an axis without any such epoch keeps the
    changes). "run" by default: the changes' shape follows the motion, their size is not
    the coplanar deskewing's error (0.04-0.8 of its sigma per axis on four laps). Ten laps,
    batch with loops (world 4 not run), mean NEES5 inside [0.83, 12.8] on 14 of 18 runs
    against 8 (6 mm 8 of 9, median 0.98 -> 6.0; 2 cm 6 of 9, 0.70 -> 3.4); none too
    cautious any more (lowest 1.46 against 0.11), but 4 above, 2 of them inside before
    (2 cm: world 16 9.5 -> 20, 18 12.2 -> 71), and the two above before rise (world 18 at
    6 mm 25 -> 207, world 0 at 2 cm 19.5 -> 47; with the true deskewing errors' scale, a
    diagnostic, 255 and 65: their excess is not the deskewing; docs/RESULTS.md). The
    same cost as "none". "epoch" sizes each epoch's error as the coplanar twist
    fit's: the "run" value (the first epoch: its first step's covariance) narrowed by what
    the epoch's own planes fix of the twist (:mod:`planodom.smoothing.deskew_epoch`).
    Only the covariances change. Off: right epoch by epoch on a good 6 mm lap, too small
    at 2 cm (the motion within the epoch), and the laps inside the NEES interval fall from
    7 to 4 of 14 at 2 cm and 5 to 0 of 9 at 6 mm (docs/RESULTS.md, NEESRUN)."""
    sandwich_undeskewed: Literal["none", "motion"] = "motion"
    """With ``covariance_model`` "sandwich" (or "auto" where it gives the sandwich): the
    deskewing error of an epoch the odometry kept without deskewing although its points
    were spread in time. "motion" adds to its covariance that of the whole motion over its
    points' times (:mod:`planodom.smoothing.undeskewed`: such an epoch's planes are off by
    the motion, not by its change); "none" gives it the changes of motion like any other
    epoch (the previous release). Only the covariances change: mean NEES5 on held-out world
    22 at 2 cm (31 such epochs) 31.8 -> 13.1, on 6 more held-out runs with 1-6 of them
    within 4 %, runs without them unchanged (docs/RESULTS.md, NEESHI)."""
    sandwich_unmeasured: Literal["change", "motion"] = "change"
    """With the sandwich covariances: the deskewing error of an epoch no step into was
    measured (its delta = 1 step unresolved, bridged by the held velocity; spread in time,
    not already kept without deskewing). "change" (default, as before) the run's changes
    of motion like any epoch; "motion" adds the whole motion over its points' times, the
    bridged step's motion times the points' span over the interval (:mod:`planodom.
    smoothing.unmeasured`): its twist was never measured, and in a gap no change of motion
    is measured around it. Derived as ``sandwich_undeskewed`` "motion", not fitted; the
    trace that led to it is world 292 at 6 mm, a lap developed on. Only the covariances
    change. Off: on the fresh laps 320-326 the count inside the NEES interval stays 2 of 4
    at 6 mm and 4 of 4 at 2 cm (the lost lap 322 at 6 mm 1.5e5 -> 5.4e4; docs/RESULTS.md,
    NEESLAP)."""
    sandwich_loop_sources: Literal["independent", "shared", "deskew", "planes"] = "independent"
    """With the sandwich covariances: "shared" takes half of each loop factor's covariance
    (a relative pose beyond ``delta_max``) as an error shared by every loop factor from the
    same older epoch, solved from that epoch's same planes (:mod:`planodom.smoothing.
    loop_sources`); "deskew" sizes that shared part by the older epoch's deskewing error
    through each factor's Jacobian, in the column of that epoch's own plane factors
    (:mod:`planodom.smoothing.loop_deskew`); "independent" (default) each loop factor's
    error its own. Only the covariances change (docs/RESULTS.md, NEES2CM). Off: over the
    40 decision-lap runs "shared" has NEES5 inside [0.83, 12.8] on 10 -> 13 of 20 at 2 cm
    and 11 -> 12 of 20 at 6 mm, but world 38 at 6 mm leaves it (1.29 -> 0.71; NEESDEF);
    "deskew" takes it to 0.64 and leaves 144 at 2 cm at 16.4 (NEESJAC). "planes" sizes
    the shared part by the planes' own fit covariances: each plane a loop factor was
    solved from is one error in every loop factor (and the plane factor) that uses it,
    each factor keeping its own variance (:mod:`planodom.smoothing.loop_planes`;
    docs/RESULTS.md, LOOPNEES)."""
    sandwich_first_epoch: Literal["motion", "step", "degenerate_step"] = "motion"
    """With the sandwich covariances: the first epoch's deskewing error. "motion"
    (default) the run's changes of motion like any epoch; "step" adds its first step's
    declared covariance times (span / interval)^2: it was deskewed with that step's twist,
    which the changes cannot size where the step was degenerate (:mod:`planodom.
    smoothing.first_epoch_noise`); "degenerate_step" adds it only where that step was
    degenerate. Only the covariances change. Off: "step" takes world 30 at 6 mm out of
    the interval (docs/RESULTS.md, NEESFIRST)."""
    sandwich_relative_ends: Literal["none", "both", "loops"] = "none"
    """With the sandwich covariances: "both" gives every relative-pose factor (steps within
    ``delta_max``, rotation-only steps, loop factors) both its epochs' deskewing errors, in
    those epochs' own columns: the change of the relative pose fitted to its plane pairs
    when either epoch's planes move by their deskewing Jacobians (:mod:`planodom.smoothing.
    relative_deskew`; it includes ``sandwich_loop_sources`` "deskew"'s older end, which it
    then replaces); "loops" the same for the kept loop factors alone (the steps' errors
    their own: NEES6 found the gains and losses in the loop factors' maps, the steps' maps
    cost the CPU); "none" (default) those factors' errors their own. Only the covariances
    change; the sizes are the run's ``Q_k``, nothing fitted (docs/RESULTS.md, NEES6,
    LOOP0)."""
    sandwich_plane_share: Literal["off", "own"] = "off"
    """Batch, with the sandwich covariances: "own" gives every plane factor's noise model
    its own share of its epoch's deskewing error, ``J Q_k J^T`` (``J`` the plane's
    ``deskew_jacobian`` in the factor's tangent coordinates, ``Q_k`` the sandwich's size of
    the epoch's error), so that a plane the deskewing moves much weighs less in the
    estimate; the sandwich then carries only the part the epoch's planes share, ``G Q G^T``
    less each factor's own block (:mod:`planodom.smoothing.plane_share`), and the modelled
    error stays the same. The estimate changes (weights, gate, loop ties); the fixed-lag
    smoother and its initial guess do not. "off" (default): the noise models hold the fits'
    covariances alone, the sandwich all of ``G Q G^T``. Off: on the 2D-rig laps of worlds
    280-298 the laps' mean NEES5 rises (inside [0.83, 12.8]: 8 -> 8 of 10 at 6 mm, 8 -> 7 at
    2 cm) and the batch ATE moves both ways (2 cm: world 292 0.118 -> 0.175 m; 6 mm: 298
    0.155 -> 0.070 m; geometric mean 1.027x; docs/RESULTS.md, NEESPLANE)."""
    covariance_scale_estimate: Literal["keep", "resolve"] = "keep"
    """With ``covariance_scale``: "keep" the estimate (only the covariances change);
    "resolve" Gauss-Newton on the reweighted graph (the covariance graph: robust inliers
    with their Gaussian twin, outliers under the kernel) from the estimate, the variance
    factors estimated again at each step. Ten laps with "groups": ATE better on 10 of 20
    runs (world 6 at 6 mm 0.078 -> 0.066 m, world 4 at 2 cm 0.069 -> 0.057 m), worse on
    10 (world 16 at 6 mm 0.025 -> 0.048 m, world 0 at 2 cm 0.148 -> 0.184 m, world 10 at
    2 cm 0.024 -> 0.037 m); urban-canyon continuous 6 mm 0.035 -> 0.040 m. Off."""

    @model_validator(mode="after")
    def _plane_share_needs_the_sandwich(self) -> CovarianceScaleConfig:
        """``sandwich_plane_share`` "own" moves part of the sandwich's deskewing error into
        the noise models: it needs the sandwich (not "fitted"; no ``deskew_noise`` or
        ``covariance_scale``, which change the noise models themselves)."""
        if self.sandwich_plane_share != "off" and (
            self.covariance_model == "fitted"
            or getattr(self, "deskew_noise", "none") != "none"
            or self.covariance_scale != "none"
        ):
            raise ConfigError(
                "smoothing.sandwich_plane_share: 'own' needs the sandwich covariances "
                "(covariance_model 'auto' or 'sandwich', deskew_noise and covariance_scale "
                "'none')"
            )
        return self
