"""Custom GTSAM factors for planodom."""
