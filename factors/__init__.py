"""Custom GTSAM factors for planodom.

- :mod:`factors.pose5`: :func:`~factors.pose5.pose5_factor` (roll, pitch, yaw, x, y of a
  relative pose; z free), :func:`~factors.pose5.rotation_factor` (its rotation rows),
  :func:`~factors.pose5.vertical_factor` (change of height); ``gtsam.CustomFactor`` with
  analytic Jacobians.
- :mod:`factors.planes`: plane landmark factors, global (``gtsam.OrientedPlane3Factor``)
  and anchored (``gtsam_unstable.LocalOrientedPlane3Factor`` with an anchor frame), their
  noise model from a plane fit covariance, and the flipped-normal guard.
"""
