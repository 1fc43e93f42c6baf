"""Planes that are not planes on the 2D rig, against the simulator's truth (issues 11, 14).

For procedural worlds (even seeds: the 2D rig) at a range noise, the streaming odometry as
``planodom experiment generalisation`` runs it (default config, or ``-c`` overrides), with
every extraction's inliers recorded. A plane the odometry kept for an epoch is a
*phantom* when its normal lies more than 5 deg from the true surface of the majority of
its inliers (base frame at the epoch's true pose), or when no surface holds half of them;
coplanar surfaces (one wall built of several pieces) count as one (:func:`plane_labels`).
Printed per world (and appended to ``-o`` as JSON lines): planes, phantoms, epochs with
one, unresolved epochs, rotation and xy rms per epoch, ATE (xy, origin-aligned, as the
generalisation experiment). With ``--detail``, per phantom: the epoch's status, how it
was extracted (with a twist, or in time windows without one), the largest tilt of one
ring's lines of several sweeps about the plane (:mod:`planodom.extraction.rig2d.
sweeptilt`, here from time bins of 1/75 s), its rings with their sweeps and labels, the
angle between the plane and each ring's own scan plane and each ring's sensor distance to
it; and the tilts of the phantoms and of the true planes.

    uv run python experiments/phantom_planes.py --worlds 20 32 --noise 0.006 --epochs 150
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

import numpy as np

import planodom.extraction.pipeline as pipeline
import planodom.extraction.rig2d.windows as pipeline_windows
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform, transform_planes
from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields

RECORD: dict[int, tuple] = {}
TILTS: list = []
_ORIGINAL = pipeline._result


def _spy(found, mode, points):  # noqa: ANN001, ANN202
    out = _ORIGINAL(found, mode, points)
    for p, idx in zip(out.planes, out.inliers, strict=True):
        RECORD[id(p)] = (p, idx, points, LAST[0])
    return out


LAST = ["?"]
_PATH = pipeline.rig2d_planes


def _path(epoch, config):  # noqa: ANN001, ANN202
    tw = config.time_windows
    windowed = pipeline_windows.is_windowed(epoch.scan, epoch.twist, tw)
    LAST[0] = "windowed" if windowed else ("twist" if epoch.twist is not None else "none")
    return _PATH(epoch, config)


pipeline._result = _spy
pipeline.rig2d_planes = _path


def plane_labels(scene) -> dict[int, int]:  # noqa: ANN001
    """Each surface id of ``scene`` to the smallest id of the surfaces coplanar with it
    (normals within 0.01 deg either way, offsets within 1 mm): a wall the procedural
    worlds build of several coplanar pieces is one plane to the extraction (world 16's
    surfaces 12-14)."""
    n, d, ids = scene.normals, scene.offsets, [int(i) for i in scene.ids]
    cos = n @ n.T
    sgn = np.where(cos < 0, -1.0, 1.0)
    same = (np.abs(cos) >= np.cos(np.radians(0.01))) & (np.abs(sgn * d[:, None] - d) <= 1e-3)
    return {ids[i]: min(ids[j] for j in np.flatnonzero(same[i])) for i in range(len(ids))}


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Unoriented angle between unit vectors (deg)."""
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b)), abs(a @ b))))


def sweep_stack(p, idx, pts, scan, sigma) -> tuple[float, float]:
    """Over the rings of a plane with lines of two or more sweeps: the largest tilt (deg)
    of a ring's sweep lines about the plane (atan of the spread of their mean offsets
    across the plane over their spread within it, across the line), counted only when
    the offsets' spread is over 4 sigma of the means; and the largest offsets' spread (m)."""
    best, stack = 0.0, 0.0
    ring, t = scan.ring[idx], scan.t[idx]
    q = pts[idx]
    res = q @ p.normal + p.offset
    for r in np.unique(ring):
        m = ring == r
        if m.sum() < 10:
            continue
        c = q[m] - q[m].mean(axis=0)
        c = c - np.outer(c @ p.normal, p.normal)
        u = np.linalg.svd(c, full_matrices=False)[2][0]
        w = np.cross(p.normal, u)
        sweep = np.floor(t[m] * 75.0 + 1e-6).astype(int)
        sel = [sweep == s for s in np.unique(sweep) if (sweep == s).sum() >= 5]
        if len(sel) < 2:
            continue
        out = np.array([res[m][k].mean() for k in sel])
        inp = np.array([(c[k] @ w).mean() for k in sel])
        nmin = min(int(k.sum()) for k in sel)
        spread_out = float(out.max() - out.min())
        stack = max(stack, spread_out)
        if spread_out < 4 * sigma * np.sqrt(2.0 / nmin):
            continue
        best = max(best, float(np.degrees(np.arctan2(spread_out, np.ptp(inp)))))
    return best, stack


def odometry_of(seed: int, noise: float, epochs: int, overrides: dict, source: str):  # noqa: ANN201
    """World ``seed`` simulated with every field and its odometry under ``overrides``
    (``source`` names them in errors), the extractions recorded afresh in ``RECORD``:
    ``(world, full, cfg, odo)``."""
    world = world_for(seed)
    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    cfg = PlanodomConfig()
    if overrides:
        cfg = cfg.updated(overrides, source=source)
    RECORD.clear()
    return world, full, cfg, run_odometry(world_fields(world, full), cfg)


def run_world(seed: int, noise: float, epochs: int, overrides: dict, detail: bool) -> dict:
    world, full, _, odo = odometry_of(seed, noise, epochs, overrides, "phantom_planes")
    rig = world.sensor_rig
    offsets = rig.ring_offsets
    scan_normals = {int(offsets[i]): s.T_base_sensor[:3, 2] for i, s in enumerate(rig.sensors)}
    origins = rig.sensor_origins
    scene = full.scene
    canon = plane_labels(scene)
    n_planes = n_phantom = 0
    phantom_epochs = []
    for k, planes in enumerate(odo.planes):
        T_base_world = invert_transform(full.poses[k])
        n_true, d_true = transform_planes(T_base_world, scene.normals, scene.offsets)
        row = {int(i): j for j, i in enumerate(scene.ids)}
        scan = full.scans[k]
        assert scan.label is not None and scan.ring is not None and scan.t is not None
        for p in planes:
            n_planes += 1
            rec = RECORD.get(id(p))
            labels = scan.label[rec[1]] if rec is not None else np.zeros(0, int)
            cnt = Counter(canon.get(x, x) for x in labels.tolist())
            lab, c = cnt.most_common(1)[0] if cnt else (-1, 0)
            ang = angle_deg(p.normal, n_true[row[lab]]) if lab in row else 90.0
            pure = 2 * c >= max(len(labels), 1)
            bad = not (ang <= 5.0 and pure)
            if rec is not None:
                TILTS.append((bad, sweep_stack(p, rec[1], rec[2], scan, noise)))
            if not bad:
                continue
            n_phantom += 1
            phantom_epochs.append(k)
            if not detail or rec is None:
                continue
            idx, pts = rec[1], rec[2]
            rings = scan.ring[idx]
            t = scan.t[idx]
            info = []
            for r in np.unique(rings):
                m = rings == r
                sn = scan_normals.get(int(r))
                on = abs(p.normal @ origins[r] + p.offset)
                rng = float(np.median(np.linalg.norm(pts[idx[m]] - origins[r], axis=1)))
                sweeps = len(np.unique(np.round(t[m] * 75.0)))
                info.append(
                    f"ring {r}: {m.sum()} pts, {sweeps} sweeps, vs own scan plane "
                    f"{angle_deg(p.normal, sn) if sn is not None else float('nan'):.1f} deg, "
                    f"sensor {on:.2f} m off at range {rng:.1f} m, labels "
                    f"{dict(Counter(labels[m].tolist()).most_common(3))}"
                )
            cov = np.zeros((4, 4)) if p.covariance is None else p.covariance
            sig = np.degrees(np.sqrt(max(np.linalg.eigvalsh(cov[:3, :3])[-1], 0)))
            print(
                f"  epoch {k} [{odo.statuses[k]}, {rec[3]}] tilt {TILTS[-1][1][0]:.0f} deg "
                f"stack {1000 * TILTS[-1][1][1]:.1f} mm: {len(idx)} pts, {ang:.1f} deg off surface "
                f"{lab} ({c}/{len(labels)}), normal {np.round(p.normal, 3)}, sigma {sig:.3f} deg"
            )
            for s in info:
                print("     " + s)
    err = per_epoch_errors(
        relative_motions(odo.poses),
        relative_motions(invert_transform(full.poses[0])[None] @ full.poses),
    )
    rot = np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))
    xy = np.hypot(err["x"], err["y"])
    gt = invert_transform(full.poses[0])[None] @ full.poses
    if detail:
        sb = sorted(round(x[0]) for b, x in TILTS if b)
        sg = sorted(round(x[0]) for b, x in TILTS if not b)
        print("tilt deg, phantoms:", sb)
        print(
            f"tilt deg, {len(sg)} true planes: 99th pct {np.percentile(sg, 99):.0f}, top", sg[-10:]
        )
    TILTS.clear()
    return {
        "world": seed, "noise": noise, "planes": n_planes, "phantoms": n_phantom,
        "phantom_epochs": len(set(phantom_epochs)), "unresolved": odo.n_unresolved,
        "rot_rms_deg": float(np.sqrt(np.mean(rot**2))),
        "xy_rms_m": float(np.sqrt(np.mean(xy**2))),
        "ate_xy_m": ate(odo.poses, gt, align="origin", xy_only=True)["rmse"],
    }  # fmt: skip


def world_parser(doc: str, overrides: bool = True) -> argparse.ArgumentParser:
    """The arguments the phantom scripts share: worlds, noise levels, epochs, overrides."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[20])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006])
    ap.add_argument("--epochs", type=int, default=150)
    if overrides:
        ap.add_argument("-c", "--overrides", default="{}", help="JSON config overrides")
    return ap


def append_rows(out: str | None, rows: list[dict]) -> None:
    """Append ``rows`` to ``out`` as JSON lines (nothing without ``out``)."""
    if out:
        with open(out, "a") as f:
            for r in rows:
                f.write(json.dumps(r) + "\n")


def main() -> None:
    ap = world_parser(__doc__)
    ap.add_argument("--detail", action="store_true")
    ap.add_argument("-o", "--out", help="append one JSON line per run")
    a = ap.parse_args()
    for w in a.worlds:
        for noise in a.noise:
            r = run_world(w, noise, a.epochs, json.loads(a.overrides), a.detail)
            print(json.dumps(r), flush=True)
            if a.out:
                with open(a.out, "a") as f:
                    f.write(json.dumps(r | {"overrides": a.overrides}) + "\n")


if __name__ == "__main__":
    main()
