"""``odometry.stated_deskew_noise`` (planodom.config.stated_deskew_noise)."""

from __future__ import annotations

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


def test_option_values_and_the_sandwichs_both_ends():
    config = PlanodomConfig().updated({"odometry.stated_deskew_noise": "shared"})
    assert config.extraction.deskew_jacobian  # the Jacobians the term needs
    with pytest.raises(ConfigError, match="stated_deskew_noise"):
        config.updated({"smoothing.sandwich_relative_ends": "both"})
    with pytest.raises(ConfigError, match="odometry.stated_deskew_noise"):
        PlanodomConfig().updated({"odometry.stated_deskew_noise": "planes"})
