"""A tiny KITTI odometry sequence folder with hand-checkable poses, for the reader tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

# Tr = T_cam0_velo: camera x right, y down, z forward; Velodyne x forward, y left, z up
R_TR = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
T_TR = np.array([0.0, -0.08, -0.27])
TR = np.eye(4)
TR[:3, :3], TR[:3, 3] = R_TR, T_TR
# camera poses: still; 1 m forward (cam z); 2 m forward and turned 90 deg about cam y (down)
P = np.tile(np.eye(4), (3, 1, 1))
P[1, :3, 3] = [0.0, 0.0, 1.0]
P[2, :3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]
P[2, :3, 3] = [0.0, 0.0, 2.0]
POINTS = [
    np.array([[1.0, 2.0, 3.0, 0.5], [-4.0, 5.5, -0.25, 0.1]], dtype=np.float32),
    np.array([[10.0, 0.0, 0.0, 1.0]], dtype=np.float32),
    np.array([[0.0, -3.0, 1.5, 0.0], [2.0, 2.0, 2.0, 0.0], [7.0, 8.0, 9.0, 0.0]], np.float32),
]


def make_sequence(root: Path, poses_beside: bool) -> Path:
    seq = root / "dataset" / "sequences" / "07"
    (seq / "velodyne").mkdir(parents=True)
    for k, pts in enumerate(POINTS):
        pts.tofile(seq / "velodyne" / f"{k:06d}.bin")
    proj = " ".join(["7.0"] + ["0.0"] * 11)
    tr = " ".join(f"{v:.6e}" for v in TR[:3].reshape(-1))
    lines = [f"P{i}: {proj}" for i in range(4)] + [f"Tr: {tr}"]
    (seq / "calib.txt").write_text("\n".join(lines) + "\n")
    (seq / "times.txt").write_text("0.000000e+00\n1.037359e-01\n2.074720e-01\n")
    rows = "\n".join(" ".join(f"{v:.9e}" for v in T[:3].reshape(-1)) for T in P) + "\n"
    if poses_beside:
        (seq / "poses.txt").write_text(rows)
    else:
        (root / "dataset" / "poses").mkdir()
        (root / "dataset" / "poses" / "07.txt").write_text(rows)
    return seq
