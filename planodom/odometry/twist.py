"""TEMPORARY (bit-identity check of the restructuring): gtsam's exp/log as before."""

import gtsam
import numpy as np


def se3_log(T: np.ndarray) -> np.ndarray:
    return np.asarray(gtsam.Pose3.Logmap(gtsam.Pose3(np.asarray(T, dtype=np.float64))))


def se3_exp(xi: np.ndarray) -> np.ndarray:
    return np.asarray(gtsam.Pose3.Expmap(np.asarray(xi, dtype=np.float64)).matrix())
