#!/usr/bin/env python3
"""Build a second real lidar dataset: WAVELab's Velodyne HDL-32E test sequences from libwave's
history (University of Waterloo, 2017), in planodom's dataset layout.

Source (public repository; bring it to this machine with the `fetch` tool and pass the git
directory it returns):
  --repo  wavelab/libwave   wave_odometry/tests/data/garage/ (removed from HEAD in 2019, read
          from the commits below). MIT licence (libwave LICENSE, (c) 2017 WAVELab).
Sets:
  garage  commit 855e842c ("Get data that doesn't have gaps"): 153 consecutive sweeps at 10 Hz,
          named by their Unix time (2017-08-24), binary PCD x y z intensity ring with padding
          fields '_' (a ROS velodyne_pointcloud PointXYZIR dump); indoors, cropped to a few metres
          around the sensor (no ground, z within +-1 m, nothing beyond ~10 m). The sensor stands
          still while people walk around it (up to half of a sweep's points occluded): point-to-
          plane ICP of every sweep onto the first finds at most 0.6 cm and 0.34 deg (p95 0.4 cm,
          0.14 deg), so the reference poses.tum is the identity at every sweep (this script
          checks the median nearest-neighbour distance of every sweep to the first, < 1 cm).
  lot     commit 4acf8dce: 83 sweeps 0.pcd ... 82.pcd, ASCII PCD x y z intensity ring, a
          parking lot beside a building; no times (planodom assumes 10 Hz); the later commit
          replaced them because of gaps, so some epochs may be more than 0.1 s apart.
lot has no reference trajectory: compare against KISS-ICP as a proxy.
Writes OUT/scans/000000.pcd ... (the files' bytes unchanged) and, for garage, OUT/poses.tum
(times in seconds from the first sweep, from the file names; identity poses).
usage: libwave_garage.py OUT --repo GITDIR [--set garage|lot]
"""

import argparse
import os
import re
import subprocess

import numpy as np
from scipy.spatial import cKDTree

COMMITS = {
    "garage": "855e842cd9ca1b45110f15cc9c6d449ba8922194",
    "lot": "4acf8dce532e82c0b690ef4caa99cedd32b87908",
}
COUNTS = {"garage": 153, "lot": 83}
DIR = "wave_odometry/tests/data/garage"


def git(gitdir, *args):
    out = subprocess.run(["git", "--git-dir", gitdir, *args], check=True, capture_output=True)
    return out.stdout


def read_xyz(path):
    """(N, 3) float32 x y z of a binary PCD whose first three fields are float x y z."""
    with open(path, "rb") as f:
        raw = f.read()
    header, _, body = raw.partition(b"DATA binary\n")
    lines = [line for line in header.decode().splitlines() if line[:1] != "#"]
    fields = dict(line.split(maxsplit=1) for line in lines)
    assert fields["FIELDS"].split()[:3] == ["x", "y", "z"], fields["FIELDS"]
    sizes, counts = (np.array(fields[k].split(), int) for k in ("SIZE", "COUNT"))
    n, step = int(fields["POINTS"]), int(np.sum(sizes * counts))
    rows = np.frombuffer(body[: n * step], np.uint8).reshape(n, step)
    return rows[:, :12].copy().view(np.float32)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--repo", required=True, help="git dir of wavelab/libwave")
    ap.add_argument("--set", choices=sorted(COMMITS), default="garage")
    a = ap.parse_args()
    commit = COMMITS[a.set]
    names = git(a.repo, "ls-tree", "--name-only", commit, DIR + "/").decode().split()
    if a.set == "garage":
        names = [n for n in names if re.fullmatch(r".*/\d+\.\d+\.pcd", n)]
        names.sort(key=lambda n: float(os.path.basename(n)[:-4]))
    else:
        names = [n for n in names if re.fullmatch(r".*/\d+\.pcd", n)]
        names.sort(key=lambda n: int(os.path.basename(n)[:-4]))
    if len(names) != COUNTS[a.set]:
        raise SystemExit(f"expected {COUNTS[a.set]} sweeps at {commit[:8]}, found {len(names)}")
    os.makedirs(os.path.join(a.out, "scans"), exist_ok=True)
    for i, n in enumerate(names):
        with open(os.path.join(a.out, "scans", f"{i:06d}.pcd"), "wb") as f:
            f.write(git(a.repo, "show", f"{commit}:{n}"))
    if a.set == "garage":
        first = cKDTree(read_xyz(os.path.join(a.out, "scans", "000000.pcd")))
        for i in range(1, len(names)):
            d = np.median(first.query(read_xyz(os.path.join(a.out, "scans", f"{i:06d}.pcd")))[0])
            if d > 0.01:
                raise SystemExit(f"sweep {i}: median distance {d:.3f} m to the first: not still")
        t = np.array([float(os.path.basename(n)[:-4]) for n in names])
        q = np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], (len(t), 1))
        np.savetxt(os.path.join(a.out, "poses.tum"), np.c_[t - t[0], q], fmt="%.6f")
    print(f"{a.out}: {len(names)} sweeps ({a.set}, libwave {commit[:8]})")


if __name__ == "__main__":
    main()
