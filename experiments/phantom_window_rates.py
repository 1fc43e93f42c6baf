"""How fast the window planes of a 2D-rig plane move along its normal, phantoms against true.

Without a twist the 2D-rig path fits a plane per time window and keeps one per wall
(:func:`planodom.extraction.rig2d.windows.drop_repeats`), extrapolated to the epoch's
reference time by a straight-line fit of its (n, d) over the windows' times. A true
plane's offset then moves at the base's velocity along its normal; a phantom's (two
scanners' lines on two walls, :mod:`phantom_planes`) at the rate its lines climb their
walls. Per windowed plane the odometry kept (streaming, as ``planodom experiment
generalisation``): phantom or not, its normal's z (base frame), the offset's rate (m/s,
from the fit) and windows, and the base's true velocity along the plane's normal over
the epoch (from the true poses). One JSON line per plane to ``-o``.

    uv run python experiments/phantom_window_rates.py --worlds 20 --noise 0.006 -o OUT
"""

from __future__ import annotations

from collections import Counter

import numpy as np
from phantom_planes import (  # importing it records every extraction
    RECORD,
    angle_deg,
    append_rows,
    plane_labels,
    world_parser,
)

import planodom.extraction.rig2d.windows as windows
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform, transform_planes
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields

RATES: list[tuple] = []
_DROP = windows.drop_repeats


def _drop(n, d, cen, rad, tm, tol_m, tw):  # noqa: ANN001, ANN202
    keep, n_out, d_out = _DROP(n, d, cen, rad, tm, tol_m, tw)
    c = n @ n.T
    sgn = np.where(c < 0, -1.0, 1.0)
    allow = tol_m + tw.speed_m_s * np.abs(tm[:, None] - tm[None, :])
    same = (np.abs(c) >= np.cos(np.radians(tw.repeat_deg))) & (
        np.abs(sgn * d[:, None] - d[None, :]) <= allow
    )
    for k, i in enumerate(keep):
        idx = np.concatenate([[i], np.flatnonzero(same[i] & (np.arange(len(n)) != i))])
        t, y = tm[idx], sgn[i, idx] * d[idx]
        rate = float(np.polyfit(t, y, 1)[0]) if len(idx) > 1 and np.ptp(t) > 0 else np.nan
        RATES.append((n_out[k].copy(), float(d_out[k]), rate, len(idx), float(np.ptp(t))))
    return keep, n_out, d_out


windows.drop_repeats = _drop


def run(seed: int, noise: float, epochs: int, out: str | None) -> None:
    world = world_for(seed)
    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    RECORD.clear()
    RATES.clear()
    odo = run_odometry(world_fields(world, full), PlanodomConfig())
    scene = full.scene
    row = {int(i): j for j, i in enumerate(scene.ids)}
    canon = plane_labels(scene)
    rows = []
    for k, planes in enumerate(odo.planes):
        T_bw = invert_transform(full.poses[k])
        n_true, _ = transform_planes(T_bw, scene.normals, scene.offsets)
        k1 = min(k + 1, len(full.poses) - 1)
        k0 = k1 - 1
        T_rel = invert_transform(full.poses[k0]) @ full.poses[k1]  # base motion, base frame
        dt = float(np.median(np.diff(full.times))) if hasattr(full, "times") else 0.1
        v = T_rel[:3, 3] / dt
        scan = full.scans[k]
        assert scan.label is not None
        for p in planes:
            rec = RECORD.get(id(p))
            if rec is None or rec[3] != "windowed":
                continue
            labels = scan.label[rec[1]]
            lab, c = Counter(canon.get(x, x) for x in labels.tolist()).most_common(1)[0]
            ang = angle_deg(p.normal, n_true[row[lab]]) if lab in row else 90.0
            bad = not (ang <= 5.0 and 2 * c >= len(labels))
            match = [r for r in RATES if abs(r[0] @ p.normal) > 0.9999 and
                     abs(np.sign(r[0] @ p.normal) * r[1] - p.offset) < 1e-6]  # fmt: skip
            m = match[-1] if match else (p.normal, p.offset, np.nan, 0, 0.0)
            sign = float(np.sign(m[0] @ p.normal))
            rows.append({"world": seed, "noise": noise, "epoch": k, "phantom": bad,
                         "nz": round(float(p.normal[2]), 3), "rate": sign * m[2],
                         "windows": m[3], "span": m[4], "v_along": float(v @ p.normal),
                         "v_z": float(v[2]), "speed": float(np.linalg.norm(v))})  # fmt: skip
    print(f"world {seed} noise {noise}: {len(rows)} windowed planes", flush=True)
    append_rows(out, rows)


def main() -> None:
    ap = world_parser(__doc__, overrides=False)
    ap.add_argument("-o", "--out", help="append one JSON line per plane")
    a = ap.parse_args()
    for w in a.worlds:
        for noise in a.noise:
            run(w, noise, a.epochs, a.out)


if __name__ == "__main__":
    main()
