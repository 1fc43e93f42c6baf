"""Where a smoothed lap's NEES5 excess sits, epoch by epoch, and its plane factors' own NEES
against the truth (a diagnostic, issue 14; extends ``nees_gauge.py``).

For one world and range noise, the lap as ``nees_gauge.py`` builds it (the odometry cached
with ``--cache DIR``), the batch with loops with the default covariances. Saved per epoch
(``-o OUT.npz``) and summarised:

- the pose error ``xi`` (6,) in the body tangent, the covariance ``P`` (6, 6), NEES5, the
  odometry's status into the epoch, whether it was deskewed, its planes (all, with a true
  surface), the true turn (rad) and travel (m) of the step into it;
- the planes' errors against their true surfaces in the epoch's true body frame, whitened
  by their covariances: NEES of the stack over the plane factors' model alone (``chi_0``,
  the planes' covariances as if independent), over the sandwich's model (``chi_Q``:
  ``I + A Q_k A^T``, ``A`` the whitened deskewing Jacobians) and after the epoch's
  least-squares common deskewing error is taken out (``chi_e``), each with its dof;
- NEES5 summed by kind of epoch (status, deskewed or not, turn or straight) and the share
  of the lap's sum held by its largest 5 % of epochs.

    uv run python experiments/nees_where.py --world 146 --noise 0.02 --cache DIR -o OUT.npz
"""

from __future__ import annotations

import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402  (patches the batch to capture its graph)

from planodom.geometry import invert_transform, transform_planes  # noqa: E402
from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402


def plane_chis(planes, T_world_base: np.ndarray, scene, Q: np.ndarray) -> tuple:  # noqa: ANN001
    """(chi_0, chi_Q, chi_e, dof, n_planes, n_true) of one epoch's planes against the truth."""
    n_w, d_w = transform_planes(invert_transform(T_world_base), scene.normals, scene.offsets)
    ids = {int(i): j for j, i in enumerate(scene.ids)}
    rows, rhs = [], []
    for p in planes:
        j = ids.get(int(p.truth_id)) if p.truth_id is not None else None
        if j is None or p.covariance is None:
            continue
        n, d = n_w[j], float(d_w[j])
        if p.normal @ n < 0:
            n, d = -n, -d
        err = np.append(p.normal - n, p.offset - d)
        C = np.asarray(p.covariance, dtype=float)
        w, V = np.linalg.eigh(C)
        keep = w > 1e-9 * w.max()
        W = (V[:, keep] / np.sqrt(w[keep])).T
        J = np.zeros((4, 6)) if p.deskew_jacobian is None else np.asarray(p.deskew_jacobian)
        rows.append(W @ J)
        rhs.append(W @ err)
    if not rows:
        return np.nan, np.nan, np.nan, 0, len(planes), 0, 0, np.full(6, np.nan), np.zeros((6, 6))
    A, b = np.vstack(rows), np.concatenate(rhs)
    chi0 = float(b @ b)
    S = np.eye(len(b)) + A @ Q @ A.T
    chiQ = float(b @ np.linalg.solve(S, b))
    e = np.linalg.lstsq(A, b, rcond=None)[0]
    r = b - A @ e
    rank = np.linalg.matrix_rank(A)
    return chi0, chiQ, float(r @ r), len(b), len(planes), len(rows), rank, e, A.T @ A


def summary(path: Path) -> None:
    """Print where the NEES5 of a saved lap (``-o``) sits."""
    z = np.load(path)
    n5, xi, P, chis = z["n5"], z["xi"], z["P"], z["chis"]
    status, deskewed, turn, travel = z["status"], z["deskewed"], z["turn"], z["travel"]
    E = len(n5)
    print(f"{path.name}: epochs {E} mean NEES5 {np.nanmean(n5):.2f} median {np.nanmedian(n5):.2f}")
    order = np.argsort(-np.nan_to_num(n5))
    total = np.nansum(n5)
    for frac in (0.01, 0.05, 0.2):
        m = max(1, int(frac * E))
        print(f"  largest {frac:.0%} of epochs hold {np.nansum(n5[order[:m]]) / total:.0%}")
    bins = np.array_split(np.arange(1, E), 10)
    R = z["poses"][1:, :3, :3]
    world_rot = np.einsum("kij,kj->ki", R, xi[1:, :3]) * 1e3
    print("  lap rotation mrad", np.round(world_rot.mean(axis=0), 2), "epoch 1",
          np.round(world_rot[0], 2), "rms about", np.round(world_rot.std(axis=0), 2))  # fmt: skip
    print("  by tenth:", " ".join(f"{np.nanmean(n5[b]):.1f}" for b in bins))
    sig = np.sqrt(np.diagonal(P, axis1=1, axis2=2))
    with np.errstate(invalid="ignore", divide="ignore"):
        u = xi / sig
    comp = np.nanmean(u[1:, :6] ** 2, axis=0)
    print("  e^2/P (roll pitch yaw x y z):", " ".join(f"{c:.1f}" for c in comp))
    for lag in (1, 10, 50):
        ac = [
            np.nanmean(u[1:-lag, i] * u[1 + lag :, i]) / np.nanmean(u[1:, i] ** 2) for i in range(5)
        ]
        print(f"  autocorrelation lag {lag}:", " ".join(f"{a:.2f}" for a in ac))
    groups = {"status " + s: status == s for s in sorted(set(status.tolist()))} | {
        "undeskewed": ~deskewed,
        "turn > 1 deg": np.abs(turn) > np.radians(1.0),
        "straight": np.abs(turn) <= np.radians(1.0),
    }
    for name, m in groups.items():
        m = m.copy()
        m[0] = False
        if m.any():
            print(f"  {name:24s} n {m.sum():5d} mean NEES5 {np.nanmean(n5[m]):9.2f} "
                  f"share {np.nansum(n5[m]) / total:.0%}")  # fmt: skip
    dof = chis[:, 3]
    ok = dof > 0
    c0, cq, ce = (np.nansum(chis[ok, i]) for i in range(3))
    d, r = np.nansum(dof[ok]), np.nansum(chis[ok, 6])
    print(f"  planes vs truth: chi0/dof {c0 / d:.2f}  chiQ/dof {cq / d:.2f}  "
          f"chi_e/(dof-rank) {ce / (d - r):.2f}  (planes {int(np.nansum(chis[:, 5]))} "
          f"with truth of {int(np.nansum(chis[:, 4]))})")  # fmt: skip
    top = order[: max(1, E // 20)]
    rest = np.setdiff1d(np.arange(1, E), top)
    for name, idx in (("top 5%", top), ("rest", rest)):
        idx = idx[ok[idx]]
        print(f"  {name}: chi0/dof {np.nansum(chis[idx, 0]) / np.nansum(dof[idx]):.2f} "
              f"chiQ/dof {np.nansum(chis[idx, 1]) / np.nansum(dof[idx]):.2f}")  # fmt: skip
    print("  largest epochs: k NEES5 status desk turn_deg travel_m roll pitch yaw x y (sigmas) "
          "chi0/dof chiQ/dof")  # fmt: skip
    for k in order[:15]:
        print(f"   {k:5d} {n5[k]:8.1f} {status[k]:12s} {int(deskewed[k])} "
              f"{np.degrees(turn[k]):6.2f} "
              f"{travel[k]:.3f} " + " ".join(f"{v:6.1f}" for v in u[k, :5])
              + f" {chis[k, 0] / max(dof[k], 1):6.2f}"
              f" {chis[k, 1] / max(dof[k], 1):6.2f}")  # fmt: skip


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, required=True)
    parser.add_argument("--summary", action="store_true", help="print a saved -o only")
    args = parser.parse_args()
    if args.summary:
        summary(args.output)
        return
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    path = None if args.cache is None else args.cache / f"batch_w{args.world}_{args.noise}.pkl"
    if path is not None and path.exists():
        poses, P, Q = pickle.loads(path.read_bytes())
    else:
        res = smooth_batch(odo.planes, rel, cfg)
        assert res.covariances is not None, res.covariance_note
        poses, P, Q = res.poses, res.covariances, nees_gauge.CAPTURED_Q()
        if path is not None:
            path.write_bytes(pickle.dumps((poses, P, Q)))
    E = len(gt)
    xi = pose_errors(poses, gt)
    n5 = np.full(E, np.nan)
    n5[1:] = errors_nees(xi[1:], P[1:], range(5))
    chis = np.full((E, 7), np.nan)
    desk_e, desk_info = np.full((E, 6), np.nan), np.zeros((E, 6, 6))
    for k in range(E):
        *out, desk_e[k], desk_info[k] = plane_chis(odo.planes[k], full.poses[k], full.scene, Q[k])
        chis[k] = out
    status = np.array(odo.statuses)
    deskewed = np.array(
        [r is not None and r.deskew_twist is not None for r in odo.results], dtype=bool
    )
    step = invert_transform(gt[:-1]) @ gt[1:]
    turn = np.zeros(E)
    turn[1:] = np.arctan2(step[:, 1, 0], step[:, 0, 0])
    travel = np.zeros(E)
    travel[1:] = np.linalg.norm(step[:, :2, 3], axis=1)
    np.savez(
        args.output, xi=xi, P=P, poses=poses, n5=n5, Q=Q, chis=chis, desk_e=desk_e,
        desk_info=desk_info, status=status, deskewed=deskewed,
        turn=turn, travel=travel, superseded=np.array(sorted(odo.superseded), dtype=int),
    )  # fmt: skip
    summary(args.output)


if __name__ == "__main__":
    main()
