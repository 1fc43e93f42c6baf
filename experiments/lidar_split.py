"""Where a lidar world's rotation error over the oracle comes from, split (issue 11).

``uv run python experiments/lidar_split.py W NOISE [--epochs N] [--variants a,b,...]
[--out FILE.npz]``: the generalisation experiment's world ``W`` (odd: a lidar) at range
noise NOISE (m), run by the oracle and by planodom's odometry with the truth substituted
for one stage at a time (:mod:`lidar_floor`'s variants, combined with ``+``), and one
line per variant: the rotation rms per step (deg) over all steps, over steps 1-2 and over
steps 3 on, each with its ratio to the oracle's over the same steps, the share of the
squared rotation error in steps 1-2, the xy rms per step (cm) and the ATE (xy, aligned at
the origin, mm). The variants:

- ``run``: planodom as the experiment runs it (its own deskewing, the default
  configuration with the world's sweep declared): the figure to explain.
- ``true``: the scans deskewed along the true motion (planodom's deskewing off,
  registered at the epoch times), the default otherwise: ``run`` -> ``true`` is the
  deskewing's share (with the reference time's).
- ``bias0``: also the planes' weights without the 2 cm laser bias: the weights' share.
- ``own``: also each surface the extraction found fitted from all its points (true
  segmentation, one plane per surface): the extraction's fit and split share.
- ``all``: every surface the oracle fits, found or not: the share of the surfaces the
  extraction misses.
- ``ttwist`` (with ``run``): planodom's own deskewing, but every extraction given the
  sweep's true constant twist (``log(T(t_k)^-1 T(t_k + period)) / period``) in place of
  the odometry's: the twist's share, apart from the motion's change within a sweep.
- ``tdesk`` (with ``run``, scans with point times): every extraction given the scan's
  points brought exactly along the true motion to its reference time (and a zero twist):
  the constant-twist model's share beside ``ttwist``.
- ``epoch``: ``planemap.reference_time: epoch`` (registered at the sweeps' starts).
- ``lw`` (with ``run``): ``planemap.lead_weights: stated`` (LIDARW); ``lb1``, ``lb20``
  with it: its ``led_bias_m`` 1 mm or 2 cm instead of 5 mm.
- ``b5``, ``b1``, ``fit``, ``dv``, ``r3``: :mod:`lidar_floor`'s configurations.
- ``nolead`` / ``leadfull`` (with ``run``): ``odometry.map_twist_lead: off`` / the lead
  not shrunk (``map_lead_shrink: off``), the default's two neighbours; ``acc``: with
  ``odometry.map_lead_acceleration: rate``.

With ``--out`` the file also holds each variant's poses (``poses_VARIANT``), the true
poses (``gt``) and the epoch times, for signed per-step errors and the drift.

The steps 1-2 / 3+ split answers whether the excess is the start's (LIDARSTART).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

# the walks' per-step errors and epoch sequence; the floor's oracle planes and extractor
from handheld_walks import _errors, _Scans
from lidar_floor import OVERRIDES, _extractor, _key, truly_deskewed

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep
from planodom.extraction import extract_planes
from planodom.geometry import invert_transform, se3_log
from planodom.metrics import ate
from planodom.odometry import run_odometry
from planodom.oracle import run_oracle

# the deskewing passes along the curve through the neighbouring poses (LIDARCURVE)
CURVE: dict[str, dict[str, object]] = {
    "p1": {"odometry.deskew_passes": 1},
    "p2": {"odometry.deskew_passes": 2},
    "wfit": {"odometry.deskew_fit": "weighted"},
    "ifit": {"odometry.deskew_fit": "increments"},
    "noguard": {"odometry.deskew_pass_guard": "off"},
    "mid": {"planemap.pass_reference_time": "middle"},
    # the own twist led by half an epoch along its change (odometry.map_twist_lead)
    "lead": {"odometry.map_twist_lead": "rate"},
    "leads": {"odometry.map_twist_lead": "rate", "odometry.map_lead_shrink": "stated"},
    # the led twist's error in the planes' weights, led bias 5 mm (planemap.lead_weights)
    "lw": {"planemap.lead_weights": "stated"},
    "lb1": {"planemap.led_bias_m": 0.001},  # with lw: the led scans' bias 1 mm
    "lb20": {"planemap.led_bias_m": 0.02},  # with lw: the term alone, the bias kept
    # the lead off, and led in full (not shrunk): the default's two neighbours (LIDAR9)
    "nolead": {"odometry.map_twist_lead": "off"},
    "leadfull": {"odometry.map_twist_lead": "rate", "odometry.map_lead_shrink": "off"},
    # the led epochs deskewed with the rate's change too (odometry.map_lead_acceleration)
    "acc": {"odometry.map_lead_acceleration": "rate"},
    # the led epochs' re-extraction tolerances (LIDAR13; the general deskew_* ones are
    # replaced by these under the lead): rate 0.02 deg/s, speed 1 cm/s, the vertical alone
    "rtol": {"odometry.map_lead_rate_tolerance_deg_s": 0.02},
    "stol": {"odometry.map_lead_speed_tolerance_mps": 0.01},
    "vtol": {"odometry.map_lead_vertical_tolerance_mps": 0.01},
}


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def split(rot: np.ndarray, orot: np.ndarray, head: int = 2) -> dict[str, float]:
    """Rotation rms per step (deg) over all steps, the first ``head`` and the rest, their
    ratios to the oracle's ``orot`` over the same steps, and the first steps' share of
    the squared error."""
    out = {"all": _rms(rot), "head": _rms(rot[:head]), "tail": _rms(rot[head:])}
    ref = {"all": _rms(orot), "head": _rms(orot[:head]), "tail": _rms(orot[head:])}
    out |= {f"x_{k}": out[k] / ref[k] for k in ref}
    out["share_head"] = float(np.sum(rot[:head] ** 2) / max(np.sum(rot**2), 1e-30))
    return out


def _true_twist_extractor(scans: Sequence, full, world):  # noqa: ANN001, ANN202
    """An extractor that deskews every epoch of ``scans`` (as run) with its sweep's true
    constant body twist (6,) (rad/s, m/s) from its first to its last point time (the
    simulator's), whatever twist the odometry passes."""
    index = {_key(s): k for k, s in enumerate(scans)}

    def extract(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN202
        k = index.get(_key(scan))
        extract.calls = getattr(extract, "calls", 0) + 1  # type: ignore[attr-defined]
        extract.missed = getattr(extract, "missed", 0) + (k is None)  # type: ignore[attr-defined]
        if k is not None:
            t = full.scans[k].t
            span = np.array([t.min(), t.max()]) + float(full.times[k])
            T = world.trajectory.poses(span)
            twist = se3_log(invert_transform(T[0]) @ T[1]) / (span[1] - span[0])
        return extract_planes(scan, config, twist=twist, **kwargs)

    return extract


def _true_deskew_extractor(scans: Sequence, full, world):  # noqa: ANN001, ANN202
    """An extractor that brings every epoch of ``scans`` (as run, with point times) to its
    reference time along the true motion and extracts it with a zero twist."""
    index = {_key(s): k for k, s in enumerate(scans)}

    def extract(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN202
        k = index.get(_key(scan))
        extract.calls = getattr(extract, "calls", 0) + 1  # type: ignore[attr-defined]
        extract.missed = getattr(extract, "missed", 0) + (k is None or scan.t is None)  # type: ignore[attr-defined]
        if k is None or scan.t is None:
            return extract_planes(scan, config, twist=twist, **kwargs)
        t_abs = float(full.times[k]) + full.scans[k].t  # (N,) the points' true times
        t_ref = float(t_abs[0] - scan.t[0])  # the scan's times are relative to it
        M = invert_transform(world.trajectory.pose(t_ref))[None] @ world.trajectory.poses(t_abs)
        p = np.einsum("nij,nj->ni", M[:, :3, :3], scan.points) + M[:, :3, 3]
        return extract_planes(replace(scan, points=p), config, twist=np.zeros(6), **kwargs)

    return extract


def _true_curve_run(data, gt: np.ndarray, cfg: PlanodomConfig):  # noqa: ANN001, ANN202
    """The odometry on the scans deskewed along the curve through the true poses ``gt``
    (N, 4, 4) at the epoch times (``odometry.deskew_passes`` passes to the middles, then
    one to the epoch times, :func:`planodom.odometry.run.redeskewed_run`): the floor of
    the curve's model without its nodes' errors."""
    from planodom.extraction.lidar.sweep import sweep_timed
    from planodom.odometry.run import redeskewed_run, with_motion_bounds
    from planodom.rig import Rig

    rig = getattr(data, "rig", None) or Rig()
    cfg = with_motion_bounds(cfg, rig.motion_bounds)
    source = sweep_timed(data, cfg.extraction.sweep, rig)
    return redeskewed_run(source, np.asarray(data.times), gt, cfg, rig)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("world", type=int)
    p.add_argument("noise", type=float)
    p.add_argument("--epochs", type=int, default=150)
    p.add_argument("--variants", default="run,true,bias0,own+bias0,all+bias0")
    p.add_argument("--out")
    args = p.parse_args()
    world, full, data, gt, scans, oracle = truly_deskewed(args.world, args.noise, args.epochs)
    orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
    orot, oxy = _errors(orc.poses, gt)
    oa = ate(orc.poses, gt, align="origin", xy_only=True)["rmse"]
    head = f"world {args.world} {world.description['family']} {args.noise * 1000:g} mm"
    s = split(orot, orot)
    print(f"{head} {'oracle':>10}: rot {s['all']:.5f} (1-2 {s['head']:.5f}, 3+ "
          f"{s['tail']:.5f}) xy {100 * _rms(oxy):.4f} cm ATE {1000 * oa:.2f} mm",
          flush=True)  # fmt: skip
    sweep = declared_sweep(world, PlanodomConfig())
    truth = {"odometry.deskew": False, "planemap.reference_time": "epoch"}
    out: dict[str, np.ndarray] = {"orot": orot, "oxy": oxy, "gt": gt, "times": data.times}
    for variant in args.variants.split(","):
        parts = variant.split("+")
        overrides: dict[str, object] = {} if "run" in parts else dict(truth)
        for part in parts:
            overrides |= OVERRIDES.get(part, {})
        cfg = sweep.updated(overrides, source="lidar_split") if overrides else sweep
        mode = next((m for m in ("own", "all") if m in parts), None)
        extractor = None if mode is None else _extractor(scans, oracle, mode)
        if "ttwist" in parts:
            extractor = _true_twist_extractor(data.scans, full, world)
        if "tdesk" in parts:
            extractor = _true_deskew_extractor(data.scans, full, world)
        if "epoch" in parts:
            cfg = cfg.updated({"planemap.reference_time": "epoch"}, source="lidar_split")
        for part in parts:
            if part in CURVE:
                cfg = cfg.updated(CURVE[part], source="lidar_split")
        source = data if "run" in parts else _Scans(scans, data.times)
        c0 = time.process_time()
        if "tcurve" in parts:  # deskewed along the curve through the true poses
            odo = _true_curve_run(data, gt, cfg)
        else:
            odo = run_odometry(source, cfg, extractor=extractor)
        cpu = time.process_time() - c0
        rot, xy = _errors(odo.poses, gt)
        a = ate(odo.poses, gt, align="origin", xy_only=True)["rmse"]
        s = split(rot, orot)
        top = np.argsort(rot)[::-1][:3] + 1
        print(
            f"{head} {variant:>10}: rot {s['all']:.5f} ({s['x_all']:.1f}x) 1-2 {s['head']:.5f}"
            f" ({s['x_head']:.1f}x) 3+ {s['tail']:.5f} ({s['x_tail']:.1f}x) share1-2 "
            f"{s['share_head']:.2f} xy {100 * _rms(xy):.4f} cm ({_rms(xy) / _rms(oxy):.2f}x) "
            f"ATE {1000 * a:.2f} mm ({a / oa:.1f}x) worst steps {top.tolist()} CPU {cpu:.0f} s",
            flush=True,
        )
        if hasattr(extractor, "missed"):
            print(f"  true twist: {extractor.missed} of {extractor.calls} extractions missed")  # type: ignore[union-attr]
        out[f"rot_{variant}"], out[f"xy_{variant}"] = rot, xy
        out[f"poses_{variant}"] = np.asarray(odo.poses)  # signed errors, drift (LIDAR9)
    if args.out:
        np.savez(args.out, **out)  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
