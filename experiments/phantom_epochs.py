"""Phantom planes of the 2D rig across epochs: does a kept plane reappear next epoch?

A true surface is seen again at the same place in the world by the neighbouring epochs; a
phantom (:mod:`phantom_planes`: a kept plane more than 5 deg from the true surface of most
of its inliers; on the 2D rig two scanners' lines on two different walls) is a
coincidence of where its lines lie, and its lines move along their walls with the vehicle.
For every plane the odometry kept at epoch k (the streaming odometry as ``planodom
experiment generalisation`` runs it), the planes of epochs k - 1 and k + 1 are moved into
epoch k's base frame, once by the true relative pose and once by the odometry's estimate,
and compared with it: whether the strict association (:func:`planodom.association.
strict_association`, its own margins: normals within ``strict_normal_deg``, offsets within
``strict_offset_m``, supports' bounding circles within ``overlap_margin_m``; the pose is
given, so no translation bound is added) matches it, and the residual of its nearest
neighbour among the planes whose supports overlap (normal angle, offset difference; the
smallest of angle / strict_normal_deg + |offset| / strict_offset_m). One JSON line per
plane to ``-o``; a summary per run on stdout. ``--summary OUT.jsonl`` prints the tables
of such a file instead: per noise, the phantoms and true planes each test would remove
(a plane not matched by the previous epoch, the next, both, either; with the true and the
estimated relative pose; with the association's margins and with a tighter normal gate),
how many of the removed planes the relative poses were computed from (their sources), and
the residuals of the matched planes.

    uv run python experiments/phantom_epochs.py --worlds 20 16 --noise 0.006 0.02 \
        --epochs 150 -o OUT.jsonl
    uv run python experiments/phantom_epochs.py --summary OUT.jsonl
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

from planodom.association import strict_association
from planodom.config import AssociationConfig
from planodom.geometry import invert_transform, plane_transform_jacobian, transform_planes
from planodom.planes import PlaneSet


def nearest(a: PlaneSet, b: PlaneSet, T_a_b: np.ndarray, cfg: AssociationConfig) -> list:
    """Per plane of ``a``: [matched by SDA (bool), normal angle deg, offset difference m]
    of its SDA match, else of its nearest plane of ``b`` (moved by ``T_a_b`` into a's frame)
    among those whose supports overlap (NaN when none does)."""
    out = [[False, np.nan, np.nan, np.nan] for _ in range(len(a))]
    if len(a) == 0 or len(b) == 0:
        return out
    R, t = T_a_b[:3, :3], T_a_b[:3, 3]
    pairs = strict_association(a, b, R, cfg, translation=t, translation_bound=0.0)
    n_b, d_b = transform_planes(T_a_b, b.normals, b.offsets)
    c_b = b.centroids @ R.T + t
    cos = np.clip(a.normals @ n_b.T, -1.0, 1.0)
    ang = np.degrees(np.arccos(cos))
    dd = np.abs(a.offsets[:, None] - d_b[None, :])
    gap = np.linalg.norm(a.centroids[:, None, :] - c_b[None, :, :], axis=2)
    reach = a.radii[:, None] + b.radii[None, :] + cfg.overlap_margin_m
    over = ~(gap > reach)  # unknown supports (NaN) overlap, as in SDA
    cost = np.where(over, ang / cfg.strict_normal_deg + dd / cfg.strict_offset_m, np.inf)
    matched = {int(i): int(j) for i, j in pairs}
    for i in range(len(a)):
        j = matched.get(i, int(np.argmin(cost[i])))
        if i in matched or np.isfinite(cost[i, j]):
            chi2 = whitened(a, b, i, j, T_a_b)
            out[i] = [i in matched, round(float(ang[i, j]), 3), round(float(dd[i, j]), 4), chi2]
    return out


def whitened(a: PlaneSet, b: PlaneSet, i: int, j: int, T_a_b: np.ndarray) -> float:
    """Squared whitened difference of plane ``i`` of ``a`` and plane ``j`` of ``b`` (moved
    into a's frame): ``(n, d)`` differences over the sum of their declared covariances
    (rank 3, pseudo-inverse; NaN when one is unknown)."""
    J = plane_transform_jacobian(T_a_b)
    n_b, d_b = transform_planes(T_a_b, b.normals[j : j + 1], b.offsets[j : j + 1])
    diff = np.append(a.normals[i] - n_b[0], a.offsets[i] - d_b[0])
    cov = a.covariances[i] + J @ b.covariances[j] @ J.T
    if not np.all(np.isfinite(cov)):
        return float("nan")
    return round(float(diff @ np.linalg.pinv(cov, rcond=1e-10) @ diff), 2)


def labels_of(planes: list, scan, canon: dict, n_true, row: dict) -> list[bool]:  # noqa: ANN001
    """Per plane: whether it is a phantom (:mod:`phantom_planes`'s rule)."""
    bad = []
    for p in planes:
        rec = RECORD.get(id(p))
        labels = scan.label[rec[1]] if rec is not None else np.zeros(0, int)
        cnt = Counter(canon.get(x, x) for x in labels.tolist())
        lab, c = cnt.most_common(1)[0] if cnt else (-1, 0)
        ang = angle_deg(p.normal, n_true[row[lab]]) if lab in row else 90.0
        bad.append(not (ang <= 5.0 and 2 * c >= max(len(labels), 1)))
    return bad


def sources_of(results: list, k: int) -> tuple[set, set]:
    """The plane indices of epoch ``k`` among the sources of its own relative pose (as
    current) and of the next epoch's when its reference is ``k`` (as previous)."""
    own, nxt = set(), set()
    r = results[k]
    if r is not None and r.sources is not None:
        own = {int(x) for x in r.sources[:, 1]}
    r = results[k + 1] if k + 1 < len(results) else None
    if r is not None and r.sources is not None and r.prev == k:
        nxt = {int(x) for x in r.sources[:, 0]}
    return own, nxt


def run(seed: int, noise: float, epochs: int, overrides: dict, out: str | None) -> None:
    _, full, cfg, odo = odometry_of(seed, noise, epochs, overrides, "phantom_epochs")
    scene = full.scene
    row = {int(i): j for j, i in enumerate(scene.ids)}
    canon = plane_labels(scene)
    n = len(odo.planes)
    sets = [PlaneSet.from_planes(p) for p in odo.planes]
    truth = {"true": full.poses, "est": odo.poses}
    rows = []
    for k, planes in enumerate(odo.planes):
        n_true, _ = transform_planes(invert_transform(full.poses[k]), scene.normals, scene.offsets)
        bad = labels_of(planes, full.scans[k], canon, n_true, row)
        tests = {}
        for name, P in truth.items():
            for side, m in (("prev", k - 1), ("next", k + 1)):
                if 0 <= m < n:
                    tests[f"{side}_{name}"] = nearest(
                        sets[k], sets[m], invert_transform(P[k]) @ P[m], cfg.association
                    )
        src = sources_of(odo.results, k)
        for i, p in enumerate(planes):
            rec = RECORD.get(id(p))
            rows.append({"world": seed, "noise": noise, "epoch": k, "phantom": bad[i],
                         "mode": rec[3] if rec is not None else "?",
                         "status": str(odo.statuses[k]),
                         "source": [i in src[0], i in src[1]],
                         "level_deg": round(angle_deg(p.normal, np.array([0.0, 0, 1])), 2),
                         **{key: v[i] for key, v in tests.items()}})  # fmt: skip
    n_bad = sum(r["phantom"] for r in rows)

    def kept(rs: list, key: str) -> int:
        return sum(bool(r.get(key, [False])[0]) for r in rs)

    ph = [r for r in rows if r["phantom"]]
    tr = [r for r in rows if not r["phantom"]]
    print(f"world {seed} noise {noise}: {len(rows)} planes, {n_bad} phantoms; matched next "
          f"(true pose) {kept(ph, 'next_true')} / {kept(tr, 'next_true')}, "
          f"prev {kept(ph, 'prev_true')} / {kept(tr, 'prev_true')}", flush=True)  # fmt: skip
    append_rows(out, rows)


def confirmed(r: dict, key: str, max_deg: float) -> bool:
    """Whether row ``r``'s test ``key`` (e.g. "next_est") matched it within ``max_deg``."""
    v = r.get(key)
    return v is not None and bool(v[0]) and v[1] <= max_deg


TESTS = {
    "not prev": lambda r, p, a: not confirmed(r, f"prev_{p}", a),
    "not next": lambda r, p, a: not confirmed(r, f"next_{p}", a),
    "neither": lambda r, p, a: not (confirmed(r, f"prev_{p}", a) or confirmed(r, f"next_{p}", a)),
    "not both": lambda r, p, a: not (confirmed(r, f"prev_{p}", a) and confirmed(r, f"next_{p}", a)),
}


def summarise(path: str) -> None:
    """Print the tables of a file of ``-o`` rows (see the module docstring)."""
    with open(path) as f:
        rows = [json.loads(line) for line in f]
    for noise in sorted({r["noise"] for r in rows}):
        rs = [r for r in rows if r["noise"] == noise]
        ph = [r for r in rs if r["phantom"]]
        tr = [r for r in rs if not r["phantom"]]
        print(f"noise {noise}: {len(ph)} phantoms, {len(tr)} true planes, "
              f"{len({r['world'] for r in rs})} worlds")  # fmt: skip
        for pose in ("true", "est"):
            for a in (3.0, 1.0, 0.5):
                cells = []
                for name, test in TESTS.items():
                    x = sum(test(r, pose, a) for r in ph)
                    y = sum(test(r, pose, a) for r in tr)
                    cells.append(f"{name} {x} ({100 * x / max(len(ph), 1):.0f} %) / "
                                 f"{y} ({100 * y / max(len(tr), 1):.1f} %)")  # fmt: skip
                print(f"  {pose} pose, normals within {a} deg: " + "; ".join(cells))
        for name, group in (("phantoms", ph), ("true planes", tr)):
            gone = [r for r in group if TESTS["neither"](r, "est", 3.0)]
            src = [r for r in gone if "source" in r]
            own, nxt = sum(r["source"][0] for r in src), sum(r["source"][1] for r in src)
            ang = [r["next_est"][1] for r in group if confirmed(r, "next_est", 3.0)]
            pct = np.round(np.percentile(ang, [50, 90, 99]), 3) if ang else []
            print(f"  {name}: matched by neither (est, 3 deg) {len(gone)}, of {len(src)} with "
                  f"sources {own} in their pose's, {nxt} in the next's; matched next: {len(ang)}, "
                  f"normal residual deg 50/90/99 % {pct}")  # fmt: skip


def main() -> None:
    ap = world_parser(__doc__)
    ap.add_argument("-o", "--out", help="append one JSON line per plane")
    ap.add_argument("--summary", help="print the tables of a file of -o rows and stop")
    a = ap.parse_args()
    if a.summary:
        summarise(a.summary)
        return
    for w in a.worlds:
        for noise in a.noise:
            run(w, noise, a.epochs, json.loads(a.overrides), a.out)


if __name__ == "__main__":
    main()
