"""planodom: odometry from planar landmarks."""
