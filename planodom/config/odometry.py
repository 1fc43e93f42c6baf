"""Configuration of association, consensus and the streaming odometry."""

from __future__ import annotations

from planodom.config.section import Section
from planodom.errors import ConfigError


class AssociationConfig(Section):
    """Lenient and strict data association (planodom.association).

    The absolute constraints assume a maximum motion between two consecutive epochs:
    ``max_translation_m`` and ``max_rotation_deg`` (the defaults allow 10 m/s and 200 deg/s
    at 10 Hz epochs). With a motion prior (the constant-velocity prediction) the bounds
    are ``prior_translation_m`` / ``prior_rotation_deg`` around the prior instead. A
    dataset with faster motion or a lower epoch rate must raise them (config file or
    ``rig.yaml``); when epoch k is associated with epoch k - delta, the streaming
    odometry multiplies the per-epoch bounds by delta.
    """

    parallel_angle_deg: float = 15.0
    """Plane pairs whose normals are closer than this (or to its opposite) are parallel."""
    dihedral_tol_deg: float = 5.0
    """LDA: two pairs are candidates when their dihedral angles differ by at most this."""
    max_translation_m: float = 1.0
    """Assumed maximum translation between consecutive epochs, metres (no prior)."""
    max_rotation_deg: float = 20.0
    """Assumed maximum rotation angle between consecutive epochs, degrees (no prior)."""
    prior_translation_m: float = 0.3
    """Allowed deviation from the motion prior's translation, metres."""
    prior_rotation_deg: float = 5.0
    """Allowed deviation from the motion prior's rotation, degrees."""
    normal_tol_deg: float = 5.0
    """Margin for noise on a plane normal's direction, degrees (added to rotation bounds)."""
    offset_tol_m: float = 0.2
    """Margin for noise on plane offsets and pair reference points, metres."""
    overlap_margin_m: float = 1.0
    """Margin of the support-overlap test (bounding circles of the support polygons), m."""
    strict_normal_deg: float = 3.0
    """SDA: maximum angle between a previous normal and a rotated current normal, degrees."""
    strict_offset_m: float = 0.15
    """SDA: margin on offset differences beyond the translation bound, metres."""
    min_line_verticality: float = 0.2
    """Minimum |v_z| of a pair's unit intersection direction to define a reference point."""

    def model_post_init(self, context: object, /) -> None:
        for name, value in self:
            if value is not None and not value > 0:
                raise ConfigError(f"association.{name}: must be > 0, got {value!r}")
        if self.parallel_angle_deg >= 90.0 or self.min_line_verticality > 1.0:
            raise ConfigError("association: parallel_angle_deg < 90 and min_line_verticality <= 1")


class OdometryConfig(Section):
    """Rotation / translation consensus and the divide-and-conquer pipeline.

    Pipelines (paper Fig. 3): ``"wocsc"`` = (LDA, WOCSC rotation, WOCSC translation);
    ``"sda-mean"`` = (LDA, WOCSC rotation, SDA, mean translation "cog"); ablations
    ``"ocsc"`` = unweighted consensus for both, ``"mean"`` = chordal mean rotation of all
    LDA candidates, SDA and mean translation.
    """

    pipeline: str = "wocsc"
    """One of "wocsc", "sda-mean", "ocsc", "mean"."""
    delta: int = 1
    """Associate epoch k with epoch k - delta (paper's future work: delta > 1)."""
    rotation_inlier_deg: float = 3.0
    """A plane association agrees with a rotation when the normals match within this."""
    translation_inlier_m: float = 0.1
    """A pair agrees with a translation when its reference points match within this, m."""
    truncate_rotation_deg: float | None = None
    """Truncate per-element rotation errors at this angle (None: plain squared error)."""
    truncate_translation_m: float | None = None
    """Truncate per-element translation errors at this distance, m (None: plain)."""
    translation_min_angle_deg: float = 20.0
    """Pairs closer than this to parallel give no reference point (its error grows as
    1 / sin(angle)); rotation uses every non-parallel pair."""
    condition_weights: bool = True
    """Weight a pair's reference point by ``w1 w2 sin^2(angle)`` per epoch (its intersection's
    conditioning: offset noise moves it by ~ sigma_d / sin(angle)); False: ``w1 w2`` only."""
    best_partner: bool = True
    """An element with several LDA partners (ambiguous association) is scored once, with
    its best partner under each candidate; False scores every association (all count)."""
    estimate_z: bool = True
    """Estimate the vertical translation from associated ground-like planes."""
    z_plane_max_tilt_deg: float = 30.0
    """Up-facing planes tilted less than this from horizontal give the vertical translation."""
    use_motion_prior: bool = True
    """Streaming: use the constant-velocity prediction as prior for association."""
    retry_without_prior: bool = True
    """Repeat LDA with the prior-free bounds when the prior leaves no candidate."""
    deskew: bool = True
    """Streaming: deskew each epoch with the constant-velocity twist of the last estimate."""
    deskew_iterations: int = 2
    """Streaming: extract a time-spread epoch again with its own estimate's twist, at most
    this many times (see the two tolerances below); 0: the prediction only."""
    deskew_rate_tolerance_deg_s: float = 0.5
    """Re-extract when the epoch's own angular rate differs from the one it was deskewed
    with by more than this, deg/s (0.5 deg/s smears a point 20 m away by 1.7 cm at 10 Hz;
    one epoch's rotation is far more precise)."""
    deskew_speed_tolerance_mps: float = 0.5
    """Likewise for the linear velocity, m/s; larger than the noise of one epoch's
    velocity (a few cm per epoch at 6 mm), whose smear does not grow with range."""
    velocity_window: int = 5
    """Streaming: the predicted linear velocity is the median over this many recent
    measured steps (the angular rate is the last step's)."""
    epoch_period_s: float = 0.1
    """Epoch period used when epochs come without times, seconds."""
    min_sigma_rotation_deg: float = 0.001
    """Floor of the reported per-axis rotation sigma, degrees."""
    min_sigma_translation_m: float = 0.0005
    """Floor of the reported per-axis translation sigma, metres."""

    def model_post_init(self, context: object, /) -> None:
        if self.pipeline not in ("wocsc", "sda-mean", "ocsc", "mean"):
            raise ConfigError(
                f"odometry.pipeline: expected wocsc, sda-mean, ocsc or mean, got {self.pipeline!r}"
            )
        if self.delta < 1:
            raise ConfigError(f"odometry.delta: must be >= 1, got {self.delta}")
        if self.velocity_window < 1:
            raise ConfigError(f"odometry.velocity_window: must be >= 1, got {self.velocity_window}")
        if self.deskew_iterations < 0:
            raise ConfigError(
                f"odometry.deskew_iterations: must be >= 0, got {self.deskew_iterations}"
            )
        for name, value in self:
            if isinstance(value, float) and not value > 0:
                raise ConfigError(f"odometry.{name}: must be > 0, got {value!r}")
