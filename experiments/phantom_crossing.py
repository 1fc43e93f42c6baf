"""Where the two scanners' lines of a 2D-rig plane cross, phantoms against true planes.

A phantom (:mod:`phantom_planes`: a kept plane more than 5 deg from the true surface of
most of its inliers) of the 2D rig is two scanners' lines on two different walls that meet
where the walls' common edge is, extended. This measures, for every plane the odometry
kept (the streaming odometry as ``planodom experiment generalisation`` runs it), each ring's
line in the plane (principal direction of its inliers in the plane, its extent along it)
and, for every pair of rings crossing at 2 deg or more, how far their crossing point lies
beyond each line's extent (0 on the line). One JSON line per plane to ``-o``: its label
(phantom or not), how it was extracted (twist or windowed), the rings (points, length,
range from the base origin, RMS across the line, its most common surface, the rate at
which its points move across the plane with its standard error and time span) and the
pairs (angle, excess beyond each line, range of the crossing point).

    uv run python experiments/phantom_crossing.py --worlds 20 16 --noise 0.006 0.02 \
        --epochs 150 -o OUT.jsonl
"""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
from phantom_planes import (  # importing it records every extraction
    RECORD,
    angle_deg,
    append_rows,
    odometry_of,
    plane_labels,
    world_parser,
)

from planodom.geometry import invert_transform, transform_planes


def ring_lines(normal: np.ndarray, q: np.ndarray, ring: np.ndarray, min_points: int) -> list:
    """Per ring with ``min_points`` inliers: (ring, points, centroid (3,), direction (3,),
    lo, hi (m along it), RMS across the line in the plane (m))."""
    out = []
    for r in np.unique(ring):
        m = ring == r
        if m.sum() < min_points:
            continue
        c = q[m].mean(axis=0)
        e = q[m] - c
        e = e - np.outer(e @ normal, normal)
        _, sv, vt = np.linalg.svd(e, full_matrices=False)
        u = vt[0]
        s = e @ u
        out.append((int(r), int(m.sum()), c, u, float(s.min()), float(s.max()),
                    float(sv[1] / np.sqrt(m.sum()))))  # fmt: skip
    return out


def across_rate(
    normal: np.ndarray, offset: float, q: np.ndarray, t: np.ndarray, u: np.ndarray
) -> tuple[float, float, float]:
    """A ring's points ``q`` (K, 3) m at times ``t`` (K,) s, its line's direction ``u``
    (3,): the rate (m/s) at which they move along ``normal`` (distance to the plane
    regressed on time and on the position along the line, which a sweep's times follow),
    its standard error (m/s) and the time span (s); nan without two sweeps' spread."""
    span = float(np.ptp(t)) if len(t) else 0.0
    A = np.column_stack([np.ones(len(t)), q @ u, t - t.mean()])
    res = q @ normal + offset
    coef, _, rank, _ = np.linalg.lstsq(A, res, rcond=None)
    if rank < 3 or len(t) < 6:
        return np.nan, np.nan, span
    dof = len(t) - 3
    s2 = float(np.sum((res - A @ coef) ** 2)) / dof
    cov = s2 * np.linalg.inv(A.T @ A)
    return float(coef[2]), float(np.sqrt(cov[2, 2])), span


def crossing(a: tuple, b: tuple) -> tuple[float, float, float, np.ndarray]:
    """Angle (deg) of two ring lines and the excess (m) of their crossing point beyond
    each one's extent (0 when on it); the crossing point (3,)."""
    ua, ub = a[3], b[3]
    e = a[2] - b[2]
    c = float(ua @ ub)
    den = max(1.0 - c * c, 1e-12)
    wi, wj = float(ua @ e), float(ub @ e)
    s_a = (c * wj - wi) / den
    s_b = (wj - c * wi) / den
    ex_a = max(0.0, a[4] - s_a, s_a - a[5])
    ex_b = max(0.0, b[4] - s_b, s_b - b[5])
    x = a[2] + s_a * ua
    return angle_deg(ua, ub), ex_a, ex_b, x


def run(seed: int, noise: float, epochs: int, overrides: dict, out: str | None) -> None:
    _, full, _, odo = odometry_of(seed, noise, epochs, overrides, "phantom_crossing")
    scene = full.scene
    row = {int(i): j for j, i in enumerate(scene.ids)}
    canon = plane_labels(scene)
    rows = []
    for k, planes in enumerate(odo.planes):
        n_true, _ = transform_planes(invert_transform(full.poses[k]), scene.normals, scene.offsets)
        scan = full.scans[k]
        assert scan.label is not None and scan.ring is not None and scan.t is not None
        for p in planes:
            rec = RECORD.get(id(p))
            if rec is None:
                continue
            idx, pts = rec[1], rec[2]
            labels = scan.label[idx]
            lab, c = Counter(canon.get(x, x) for x in labels.tolist()).most_common(1)[0]
            ang = angle_deg(p.normal, n_true[row[lab]]) if lab in row else 90.0
            bad = not (ang <= 5.0 and 2 * c >= len(labels))
            lines = ring_lines(p.normal, pts[idx], scan.ring[idx], 10)
            pairs = []
            for i in range(len(lines)):
                for j in range(i + 1, len(lines)):
                    a, b = lines[i], lines[j]
                    deg, ex_a, ex_b, x = crossing(a, b)
                    if deg < 2.0:
                        continue
                    pairs.append([a[0], b[0], round(deg, 2), round(ex_a, 3), round(ex_b, 3),
                                  round(float(np.linalg.norm(x)), 2)])  # fmt: skip
            rings = []
            for r in lines:
                m = scan.ring[idx] == r[0]
                rl = Counter(labels[m].tolist()).most_common(1)[0][0]
                rng = round(float(np.linalg.norm(r[2])), 2)
                rate = across_rate(p.normal, p.offset, pts[idx][m], scan.t[idx][m], r[3])
                rings.append([r[0], r[1], round(r[5] - r[4], 3), rng, round(r[6], 4), rl,
                              *(round(x, 5) for x in rate)])  # fmt: skip
            rows.append({"world": seed, "noise": noise, "epoch": k, "phantom": bad,
                         "mode": rec[3], "status": str(odo.statuses[k]), "points": len(idx),
                         "off_deg": round(ang, 1), "rings": rings, "pairs": pairs})  # fmt: skip
    n_bad = sum(r["phantom"] for r in rows)
    print(f"world {seed} noise {noise}: {len(rows)} planes, {n_bad} phantoms", flush=True)
    append_rows(out, rows)


def main() -> None:
    ap = world_parser(__doc__)
    ap.add_argument("-o", "--out", help="append one JSON line per plane")
    a = ap.parse_args()
    for w in a.worlds:
        for noise in a.noise:
            run(w, noise, a.epochs, json.loads(a.overrides), a.out)


if __name__ == "__main__":
    main()
