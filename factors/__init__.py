"""Custom GTSAM factors for planodom, installed as ``planodom_factors``.

The folder stays at the top of the repository (the design card); the wheel installs it as
``planodom_factors`` so that no bare ``factors`` package lands in site-packages
(``pyproject.toml``). Import it as ``planodom_factors``.

- :mod:`planodom_factors.pose5`: :func:`~planodom_factors.pose5.pose5_factor` (roll,
  pitch, yaw, x, y of a relative pose; z free), :func:`~planodom_factors.pose5.rotation_factor`
  (its rotation rows), :func:`~planodom_factors.pose5.vertical_factor` (change of height);
  ``gtsam.CustomFactor`` with analytic Jacobians.
- :mod:`planodom_factors.planes`: plane landmark factors, global (``gtsam.OrientedPlane3Factor``)
  and anchored (``gtsam_unstable.LocalOrientedPlane3Factor`` with an anchor frame), their
  noise model from a plane fit covariance, and the flipped-normal guard.
"""
