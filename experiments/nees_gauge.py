"""Where the smoothed laps' NEES excess sits against the truth (a diagnostic, issue 14).

For one world and range noise: one lap simulated as ``planodom experiment loops``, the
odometry run once as ``planodom smooth`` runs it (cached with ``--cache DIR``), the batch
with loops with the default covariances ("auto": the sandwich on these laps). Printed:

- per-epoch NEES5 in ten stretches of the lap and its largest epochs;
- per component (roll, pitch, yaw, x, y) the mean of ``e_i^2 / P_ii`` (chi2(1): 1);
- the lap's one rotation and shift against its first pose (as ``nees_split.py``) and the
  NEES5 with them taken out;
- the NEES5 in the gauge of epoch 1 (poses and sandwich both relative to epoch 1): what
  is left once the first epoch's own error is out of the comparison;
- per epoch 0..5 (and the lap's median) the deskewing error ``e`` (6,) that explains its
  planes' errors against the true surfaces through their ``deskew_jacobian`` (least
  squares, whitened by the planes' covariances), against the sandwich's ``Q_k`` sigmas.

    uv run python experiments/nees_gauge.py --world 20 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import argparse
import pickle
from pathlib import Path

import gtsam
import numpy as np

import planodom.smoothing.batch as batch_module
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform, transform_planes
from planodom.metrics import errors_nees, pose_errors
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.graph import X
from planodom.smoothing.marginals import FIRST_POSE_TIGHTENING
from planodom.smoothing.run import smoothing_config, smoothing_relatives
from planodom.smoothing.sandwich import (
    covariance_graph_index,
    plane_error_map,
    sandwich_pose_covariances,
)

CAPTURED: dict = {}


def _spy(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
    names = ("builder", "graph", "gaussian", "fallback", "estimate", "n", "planes", "rel")
    CAPTURED.update(dict(zip(names, args, strict=False)) | kwargs)
    out = ORIGINAL(*args, **kwargs)
    CAPTURED["estimate"] = out[0]
    return out


ORIGINAL = batch_module.batch_covariances
batch_module.batch_covariances = _spy


def gauge_sandwich(Q: np.ndarray, gauge: int) -> np.ndarray:
    """(E, 6, 6) the sandwich covariances with pose ``gauge`` held instead of the first."""
    from planodom.smoothing.batch_covariances import covariance_graph

    cfg = CAPTURED["builder"].config
    graph, est = CAPTURED["graph"], CAPTURED["estimate"]
    cov_graph = covariance_graph(graph, CAPTURED["gaussian"], est, cfg.covariance_inlier_quantile)
    index = covariance_graph_index(graph, cov_graph)
    planes = {index[i]: obs for i, obs in CAPTURED["planes"].items() if i in index}
    linear = cov_graph.linearize(est)
    stiff = FIRST_POSE_TIGHTENING / cfg.prior_sigma
    linear.add(X(gauge), stiff * np.eye(6), np.zeros(6), gtsam.noiseModel.Unit.Create(6))
    zero = est.zeroVectors()
    dims = {key: zero.at(key).size for key in est.keys()}
    maps = {}
    for i, (epoch, plane) in planes.items():
        g = plane_error_map(cov_graph.at(i), plane)
        if g is not None and np.any(Q[epoch]):
            maps[i] = (epoch, g)
    keys = [X(k) for k in range(len(Q))]
    return sandwich_pose_covariances(linear, keys, dims, maps, Q).covariances


def plane_deskew_error(planes, T_world_base: np.ndarray, scene) -> tuple[np.ndarray, float, int]:  # noqa: ANN001
    """(6,) least-squares deskewing error explaining the planes' (n, d) errors against the
    truth through their Jacobians, the whitened residual's chi2 per plane, planes used."""
    n_w, d_w = transform_planes(invert_transform(T_world_base), scene.normals, scene.offsets)
    ids = {int(i): j for j, i in enumerate(scene.ids)}
    rows, rhs = [], []
    for p in planes:
        j = ids.get(int(p.truth_id))
        if j is None or p.deskew_jacobian is None or p.covariance is None:
            continue
        n, d = n_w[j], float(d_w[j])
        if p.normal @ n < 0:
            n, d = -n, -d
        err = np.append(p.normal - n, p.offset - d)
        C = np.asarray(p.covariance, dtype=float) + 1e-12 * np.eye(4)
        w, V = np.linalg.eigh(C)
        keep = w > 1e-10 * w.max()
        W = (V[:, keep] / np.sqrt(w[keep])).T
        rows.append(W @ np.asarray(p.deskew_jacobian, dtype=float))
        rhs.append(W @ err)
    if not rows:
        return np.full(6, np.nan), np.nan, 0
    A, b = np.vstack(rows), np.concatenate(rhs)
    e = np.linalg.lstsq(A, b, rcond=None)[0]
    chi_before = float(b @ b) / len(rows)
    return e, chi_before, len(rows)


def load(world_index: int, noise: float, cache: Path | None, changes: dict | None = None):  # noqa: ANN201
    """The lap, its odometry (with config ``changes``, e.g. an odometry option; cached
    under a name that holds them) and the smoothing relatives."""
    world = world_for(world_index)
    full = simulate_world(world, noise, all_fields=True)
    cfg = PlanodomConfig().updated({"smoothing.loop_closure": True, **(changes or {})})
    tag = "".join(f"_{k}={v}" for k, v in sorted((changes or {}).items()))
    path = None if cache is None else cache / f"odo_w{world_index}_{noise}{tag}.pkl"
    if path is not None and path.exists():
        odo, rel = pickle.loads(path.read_bytes())
    else:
        odo = run_odometry(world_fields(world, full), smoothing_config(cfg))
        rel = smoothing_relatives(odo, cfg)
        if path is not None:
            path.write_bytes(pickle.dumps((odo, rel)))
    return world, full, cfg, odo, rel


def lap_parser(description: str) -> argparse.ArgumentParser:
    """The lap scripts' common arguments: ``--world``, ``--noise``, ``--cache``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--world", type=int, required=True)
    parser.add_argument("--noise", type=float, required=True)
    parser.add_argument("--cache", type=Path, default=None)
    return parser


def load_lap(args: argparse.Namespace):  # noqa: ANN201
    """:func:`load` of ``args`` (from :func:`lap_parser`), with the true poses relative to
    the first: ``(world, full, cfg, odo, rel, gt)``."""
    world, full, cfg, odo, rel = load(args.world, args.noise, args.cache)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    return world, full, cfg, odo, rel, gt


def captured_batch(args: argparse.Namespace):  # noqa: ANN201
    """The lap of ``args`` (:func:`load_lap`) smoothed in batch, with what the batch built:
    ``(lap, builder, estimate, covariance graph, its factor index)``; ``CAPTURED`` holds
    the rest (the graph, the planes)."""
    from planodom.smoothing.batch_covariances import covariance_graph
    from planodom.smoothing.sandwich import covariance_graph_index

    lap = load_lap(args)
    smooth_batch(lap[3].planes, lap[4], lap[2])
    builder, est = CAPTURED["builder"], CAPTURED["estimate"]
    cov_graph = covariance_graph(
        CAPTURED["graph"], CAPTURED["gaussian"], est, builder.config.covariance_inlier_quantile
    )
    return lap, builder, est, cov_graph, covariance_graph_index(CAPTURED["graph"], cov_graph)


def main() -> None:
    args = lap_parser(__doc__.splitlines()[0]).parse_args()
    world, full, cfg, odo, rel, gt = load_lap(args)
    res = smooth_batch(odo.planes, rel, cfg)
    E = len(gt)
    xi = pose_errors(res.poses, gt)
    P = res.covariances
    assert P is not None, res.covariance_note
    n5 = errors_nees(xi[1:], P[1:], range(5))
    print(f"world {args.world} noise {args.noise} epochs {E} model {res.covariance_model}")
    counts = {s: odo.statuses.count(s) for s in set(odo.statuses)}
    print(f"mean NEES5 {np.nanmean(n5):.2f}  statuses", counts)
    print("first steps:", odo.statuses[:6])
    bins = np.array_split(np.arange(1, E), 10)
    print("NEES5 by tenth:", " ".join(f"{np.nanmean(n5[b - 1]):.1f}" for b in bins))
    top = np.argsort(-np.nan_to_num(n5))[:8] + 1
    print("largest:", " ".join(f"{k}:{n5[k - 1]:.0f}" for k in top))
    comp = np.nanmean(xi[1:, :5] ** 2 / np.diagonal(P[1:], axis1=1, axis2=2)[:, :5], axis=0)
    print("e_i^2/P_ii (roll pitch yaw x y):", " ".join(f"{c:.1f}" for c in comp))
    world_rot = np.einsum("kij,kj->ki", res.poses[1:, :3, :3], xi[1:, :3])
    theta = world_rot.mean(axis=0)
    print("lap rotation mrad", np.round(theta * 1e3, 2), "epoch1", np.round(world_rot[0] * 1e3, 2),
          "rms about", np.round(world_rot.std(axis=0) * 1e3, 2))  # fmt: skip
    # epoch-1 gauge
    Q = CAPTURED_Q()
    P1 = gauge_sandwich(Q, 1)
    inv1 = invert_transform(res.poses[1])
    est1 = inv1[None] @ res.poses
    gt1 = invert_transform(gt[1])[None] @ gt
    xi1 = pose_errors(est1, gt1)
    keep = [k for k in range(E) if k != 1]
    n51 = errors_nees(xi1[keep], P1[keep], range(5))
    print(f"gauge epoch 1: mean NEES5 {np.nanmean(n51):.2f}; epoch 0 in it {n51[0]:.1f}")
    comp1 = np.nanmean(xi1[keep, :5] ** 2 / np.diagonal(P1[keep], axis1=1, axis2=2)[:, :5], axis=0)
    print("  e_i^2/P_ii gauge 1:", " ".join(f"{c:.1f}" for c in comp1))
    # per-epoch deskewing error of the planes
    sig = np.sqrt(np.diagonal(Q, axis1=1, axis2=2))
    for k in list(range(6)):
        e, chi, n = plane_deskew_error(odo.planes[k], full.poses[k], full.scene)
        print(f"epoch {k}: {n} planes chi/plane {chi:.1f} e(rad,m) {np.round(e, 4)} "
              f"Q sigma {np.round(sig[k], 4)}")  # fmt: skip
    es = []
    for k in range(6, E, max(1, E // 60)):
        e, chi, n = plane_deskew_error(odo.planes[k], full.poses[k], full.scene)
        if n:
            es.append(np.abs(e) / np.where(sig[k] > 0, sig[k], np.nan))
    print("lap median |e|/Q sigma:", np.round(np.nanmedian(np.array(es), axis=0), 2))


def CAPTURED_Q() -> np.ndarray:  # noqa: N802
    from planodom.smoothing.batch_covariances import sandwich_inputs

    cfg = CAPTURED["builder"].config
    Q, _ = sandwich_inputs(cfg, CAPTURED["planes"], CAPTURED["rel"], CAPTURED["n"])
    assert Q is not None
    return Q


if __name__ == "__main__":
    main()
