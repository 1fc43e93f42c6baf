"""The lidar's rotation floor against the oracle, one stage at a time (issue 11).

``uv run python experiments/lidar_floor.py W NOISE [--epochs N] [--variants a,b,...]
[--out FILE.npz]``: the generalisation experiment's world ``W`` (a lidar: odd ``W``) at
range noise NOISE (m), its scans deskewed to the epoch times along the true motion
(planodom's own deskewing off: ``odometry.deskew: false``, ``planemap.reference_time:
epoch``), then planodom's plane-map odometry with the truth substituted for one stage at a
time, one line per variant: rotation and xy rms per epoch (deg, cm; the steps after the
first), the ratio of the rotation rms to the oracle's, its median epoch, the worst epoch
and the epochs over 10x the oracle's rms. The variants (combined with ``+``):

- ``true``: the default configuration (the extraction's planes, their weights, the map).
- ``bias0``: (b) the planes' weights without the laser bias (``planemap.laser_bias_m``
  0.1 mm: the simulator has none).
- ``own``: (a) each extracted plane's surface (its ``truth_id``) fitted instead from all
  the points of that surface (the oracle's plane and moments: true segmentation), one
  plane per surface, only the surfaces the extraction found.
- ``all``: (c) every surface the oracle fits (:func:`planodom.oracle.surface_moments`),
  whether extracted or not.
- ``relmap``: (d) a map of the last scan only (``memory_scans`` 0.05, ``max_age_scans``
  1): a relative registration in place of the fusion.
- ``plain``: (e) the solver without its robust parts (``outliers: kernel``,
  ``cauchy_scale`` 1e6, ``gn_iterations`` 20).
- ``diag``: the default, and (a) measured: each extracted plane against the oracle's
  plane of its surface and the truth (:func:`diagnose`), and the planes far off in the
  worst epochs.
- configurations tried as a fix: ``dv`` (``planemap.deskew_variance: twist_change``),
  ``fit`` (``planemap.laser_bias: fitted``), ``b5`` / ``b1`` (``planemap.laser_bias_m``
  5 / 1 mm), ``r3`` (``planemap.min_rows`` 3).

A lidar without a ring field gets the simulator's rings: rows recovered from points
already deskewed are wrong (world 5 at 6 mm: 0.12 deg per epoch without them).
``--as-run``: the scans as the experiment gives them, planodom's own deskewing (the
default), for the configurations tried as a fix.

The oracle (:func:`planodom.oracle.run_oracle`) is run once per world and noise.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

# the walks' per-step errors and epoch sequence (this script runs beside it in experiments/)
from handheld_walks import _errors, _Scans

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.extraction import extract_planes
from planodom.geometry import Plane, PlaneSupport, invert_transform
from planodom.metrics import ate
from planodom.odometry import run_odometry
from planodom.oracle import run_oracle, surface_moments
from planodom.simulation.random_world import simulate_world, world_fields

OVERRIDES: dict[str, dict[str, object]] = {
    "true": {},
    "bias0": {"planemap.laser_bias_m": 1e-4},
    "relmap": {"planemap.memory_scans": 0.05, "planemap.max_age_scans": 1},
    "dv": {"planemap.deskew_variance": "twist_change"},
    "fit": {"planemap.laser_bias": "fitted"},
    "b5": {"planemap.laser_bias_m": 0.005},
    "b1": {"planemap.laser_bias_m": 0.001},
    "r3": {"planemap.min_rows": 3},
    "plain": {
        "planemap.outliers": "kernel",
        "planemap.cauchy_scale": 1e6,
        "planemap.gn_iterations": 20,
    },
}


def _oracle_planes(points: np.ndarray, labels: np.ndarray, rings) -> dict[int, Plane]:  # noqa: ANN001
    """The oracle's plane of every surface of one epoch (base frame, true-deskewed
    ``points`` (N, 3)), by surface id: TLS normal towards the sensor, moments, scan lines."""
    m = surface_moments(points, labels)
    out = {}
    for k, sid in enumerate(m.ids):
        n, d, c = m.normal[k], float(m.offset[k]), m.centroid[k]
        if d < 0:
            n, d = -n, -d
        N = int(m.count[k])
        w, V = np.linalg.eigh(m.scatter[k])
        sigma2 = max(w[0] / max(N - 3, 1), 1e-8)
        # TLS covariance of (n, d) (as planodom.extraction.planes.fit.tls_covariance)
        cov_n = sum(sigma2 * w[i] / (w[i] - w[0]) ** 2 * np.outer(V[:, i], V[:, i]) for i in (1, 2))
        cov = np.zeros((4, 4))
        cov[:3, :3], cov[:3, 3], cov[3, :3] = cov_n, -cov_n @ c, -cov_n @ c
        cov[3, 3] = c @ cov_n @ c + sigma2 / N
        rows = 0 if rings is None else len(np.unique(rings[labels == sid]))
        support = PlaneSupport(c, n_points=N, scatter=m.scatter[k], n_rows=rows)
        out[int(sid)] = Plane(n, d, covariance=cov, support=support, truth_id=int(sid))
    return out


def _key(scan) -> bytes:  # noqa: ANN001
    """A scan's identity that survives copies (the odometry may add fields)."""
    return len(scan.points).to_bytes(8, "little") + scan.points[[0, -1]].tobytes()


def _extractor(scans: list, oracle: list[dict[int, Plane]], mode: str):  # noqa: ANN202
    """An extractor that hands the odometry the oracle's planes: ``own`` those of the
    surfaces the extraction found (one each), ``all`` every one."""
    index = {_key(s): k for k, s in enumerate(scans)}

    def extract(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN202
        planes = oracle[index[_key(scan)]]
        if mode == "all":
            return list(planes.values())
        found = {p.truth_id for p in extract_planes(scan, config, twist=twist, **kwargs)}
        return [planes[s] for s in sorted(found) if s in planes]

    return extract


def _recording(scans: list, record: dict):  # noqa: ANN202
    """The default extractor, keeping the last planes extracted of every epoch."""
    index = {_key(s): k for k, s in enumerate(scans)}

    def extract(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN202
        planes = extract_planes(scan, config, twist=twist, **kwargs)
        record[index[_key(scan)]] = planes
        return planes

    return extract


def diagnose(world, times, record: dict, oracle: list[dict[int, Plane]], worst=()) -> str:  # noqa: ANN001
    """(a): the extracted planes against the oracle's plane of their surface and the
    truth: normal angle (deg) and mean signed distance of the inliers to the true plane
    (mm, at the centroid), the normal error over its point-noise sigma (``sigma /
    sqrt(lam_2)``, the weight without the laser bias), planes per surface, points and
    scan lines against the oracle's."""
    rows = []
    for k, planes in sorted(record.items()):
        T = world.trajectory.pose(float(times[k]))
        per: dict[int, int] = {}
        for p in planes:
            per[p.truth_id] = per.get(p.truth_id, 0) + 1
        for p in planes:
            o = oracle[k].get(p.truth_id)
            if o is None or p.support is None or p.support.scatter is None:
                continue
            sf = world.scene.by_id(p.truth_id)
            n = sf.normal @ T[:3, :3]
            d = sf.offset + sf.normal @ T[:3, 3]
            n, d = (n, d) if n @ p.normal > 0 else (-n, -d)
            lam = np.linalg.eigvalsh(p.support.scatter)
            sig = np.sqrt(lam[0] / p.support.n_points) / np.sqrt(max(lam[1], 1e-12))
            a_e = np.degrees(np.arccos(min(abs(n @ p.normal), 1.0)))
            a_o = np.degrees(np.arccos(min(abs(n @ o.normal), 1.0)))
            assert o.support is not None
            if np.radians(a_e) / sig > 5 and k in worst:
                print(f"  epoch {k} surface {p.truth_id} ({per[p.truth_id]} planes): N "
                      f"{p.support.n_points}/{o.support.n_points}, lines {p.support.n_rows}"
                      f"/{o.support.n_rows}, angle {a_e:.4f} deg, z {np.radians(a_e) / sig:.1f}, "
                      f"offset {1e3 * (n @ p.support.centroid + d):.2f} mm")  # fmt: skip
            rows.append((a_e, a_o, 1e3 * (n @ p.support.centroid + d),
                         1e3 * (n @ o.support.centroid + d), np.radians(a_e) / sig,
                         per[p.truth_id], p.support.n_points / o.support.n_points,
                         p.support.n_rows / max(o.support.n_rows, 1)))  # fmt: skip
    r = np.array(rows)
    q = lambda x: f"{np.median(x):.4f}/{np.percentile(x, 90):.4f}"  # noqa: E731
    return (
        f"(a) {len(r)} planes: angle deg med/p90 {q(r[:, 0])} (oracle {q(r[:, 1])}), "
        f"offset mm |med|/p90 {q(np.abs(r[:, 2]))} (oracle {q(np.abs(r[:, 3]))}), "
        f"z {q(r[:, 4])}, >3 sigma {np.mean(r[:, 4] > 3):.2f}, split {np.mean(r[:, 5] > 1):.2f},"
        f" points {q(r[:, 6])}, lines {q(r[:, 7])}"
    )


def truly_deskewed(index: int, noise: float, epochs: int, untimed: str = "sweep"):  # noqa: ANN201
    """World ``index`` simulated at range noise ``noise`` (m) for ``epochs`` epochs: the
    world, the full simulation, its fields as a recording gives them, the true poses from
    the first epoch (k, 4, 4), each scan's points moved along the true motion to its epoch
    time (``untimed == "times"``: with the true point times kept) and the oracle's planes
    per scan."""
    world = world_for(index)
    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    data = world_fields(world, full)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    scans, oracle = [], []
    for k, (scan, timed) in enumerate(zip(data.scans, full.scans, strict=True)):
        t_k = full.times[k]
        M = invert_transform(world.trajectory.pose(t_k))[None] @ world.trajectory.poses(
            t_k + timed.t
        )
        points = np.einsum("nij,nj->ni", M[:, :3, :3], timed.points) + M[:, :3, 3]
        if untimed == "times":
            scan = replace(scan, t=timed.t)
        if scan.ring is None:  # rows recovered from the deskewed points would be wrong
            scan = replace(scan, ring=timed.ring)
        scans.append(replace(scan, points=points))
        assert timed.label is not None  # the simulator labels every point
        oracle.append(_oracle_planes(points, timed.label, timed.ring))
    return world, full, data, gt, scans, oracle


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("world", type=int)
    p.add_argument("noise", type=float)
    p.add_argument("--epochs", type=int, default=150)
    p.add_argument("--variants", default="true,bias0,own,own+bias0,all+bias0,relmap,plain")
    p.add_argument("--out")
    p.add_argument("--as-run", action="store_true", help="planodom's own deskewing")
    p.add_argument("--untimed", choices=["sweep", "none", "times"], default="sweep")
    args = p.parse_args()
    world, full, data, gt, scans, oracle = truly_deskewed(
        args.world, args.noise, args.epochs, args.untimed
    )
    source = data if args.as_run else _Scans(scans, data.times)
    orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
    orot, oxy = _errors(orc.poses, gt)
    o_rms = float(np.sqrt(np.mean(orot**2)))
    head = f"world {args.world} {world.description['family']} {args.noise * 1000:g} mm"
    print(f"{head} oracle: rotation {o_rms:.5f} deg, xy {100 * np.sqrt(np.mean(oxy**2)):.4f} cm",
          flush=True)  # fmt: skip
    base = PlanodomConfig()
    if args.as_run or args.untimed != "none":
        base = declared_sweep(world, base)
    if not args.as_run:
        truth = {"odometry.deskew": False, "planemap.reference_time": "epoch"}
        base = base.updated(truth, source="lidar_floor")
    out: dict[str, np.ndarray] = {"orot": orot, "oxy": oxy}
    for variant in args.variants.split(","):
        parts = variant.split("+")
        overrides: dict[str, object] = {}
        for part in parts:
            overrides |= OVERRIDES.get(part, {})
        cfg = base.updated(overrides, source="lidar_floor") if overrides else base
        mode = next((m for m in ("own", "all") if m in parts), None)
        extractor = None if mode is None else _extractor(scans, oracle, mode)
        record: dict = {}
        if "diag" in parts and not args.as_run:
            extractor = _recording(scans, record)
        c0 = time.process_time()
        odo = run_odometry(source, cfg, extractor=extractor)
        cpu = time.process_time() - c0
        rot, xy = _errors(odo.poses, gt)
        rms = float(np.sqrt(np.mean(rot**2)))
        a = ate(odo.poses, gt, align="origin", xy_only=True)["rmse"]
        worst = int(np.argmax(rot))
        bad = np.flatnonzero(rot > 10 * o_rms) + 1
        print(
            f"{head} {variant:>12}: rotation {rms:.5f} deg ({rms / o_rms:.1f}x), median "
            f"{np.median(rot):.5f} (oracle {np.median(orot):.5f}), xy "
            f"{100 * np.sqrt(np.mean(xy**2)):.4f} cm, ATE {1000 * a:.2f} mm, worst epoch "
            f"{worst + 1} {rot[worst]:.4f} deg, over 10x: {bad.tolist()[:12]}, CPU {cpu:.0f} s",
            flush=True,
        )
        if record:
            spikes = set(np.argsort(rot)[-4:] + 1)
            print(f"{head} {variant:>12}: {diagnose(world, full.times, record, oracle, spikes)}")
        out[f"rot_{variant}"], out[f"xy_{variant}"] = rot, xy
        out[f"n_{variant}"] = np.asarray(odo.n_planes)
    if args.out:
        np.savez(args.out, **out)  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
