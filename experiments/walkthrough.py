"""One epoch pair of the paper's rig, step by step, with pictures; then a short smoothing run.

    uv run python experiments/walkthrough.py [--out walkthrough] [--epochs 20]

Writes ``walkthrough.png`` (six panels: the scan lines; the extracted planes of both
epochs; the LDA pair associations as rotation candidates; the consensus scores of the
rotation and translation candidates; the winner against the truth; epoch 1's planes
moved into epoch 0 by the refined pose) and ``smoothing.png`` (odometry and batch
smoothing over the truth), and prints each step. ``tests/test_walkthrough.py`` runs it
at small size.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import planodom
from planodom.geometry import invert_transform, pose5_from_transform, rpy_from_rotation
from planodom.plots import pyplot, save
from planodom.plots.trajectory import plot_trajectory
from planodom.simulation import simulate_named


def draw_planes(ax, planes, T=None, style="-", label="") -> None:
    """Supports of ``planes`` (moved by ``T`` (4, 4)) in the top view, a normal arrow at each."""
    T = np.eye(4) if T is None else T
    for i, p in enumerate(planes):
        if p.support is None or len(p.support.polygon) < 3:
            continue
        poly = (T[:3, :3] @ p.support.polygon.T).T + T[:3, 3]
        c, n = T[:3, :3] @ p.support.centroid + T[:3, 3], T[:3, :3] @ p.normal
        ax.plot(*np.vstack([poly, poly[:1]])[:, :2].T, style, color=f"C{i % 10}", lw=1.2)
        if abs(n[2]) < 0.9:  # walls: an arrow; the ground is seen from above
            ax.arrow(c[0], c[1], n[0], n[1], head_width=0.25, color=f"C{i % 10}")
    ax.plot([], [], style, color="0.3", label=label)


def epoch_pair(ax, run, config, k: int = 1) -> planodom.RelativePose:
    """Panels 1-6 for epochs k-1 and k; returns the relative pose."""
    scans = run[k - 1], run[k]
    origins = run.rig.sensor_origins
    planes = [planodom.extract_planes(s, config.extraction, sensor_origins=origins) for s in scans]
    rel = planodom.estimate_relative_pose(planes[0], planes[1], config)
    truth = invert_transform(run.poses[k - 1]) @ run.poses[k]
    print(f"1. scans: {len(scans[0])} and {len(scans[1])} points, rings {np.unique(scans[0].ring)}")
    for j in np.unique(scans[0].ring):
        pts = scans[0].points[scans[0].ring == j]
        ax[0, 0].plot(pts[:, 0], pts[:, 1], ".", ms=1, label=f"scanner {j}")
    ax[0, 0].set_title(f"1. scan lines of epoch {k - 1} (base frame)")
    ax[0, 0].legend(markerscale=8, fontsize=7)
    print(f"2. planes: {len(planes[0])} and {len(planes[1])}")
    draw_planes(ax[0, 1], planes[0], label=f"epoch {k - 1}")
    draw_planes(ax[0, 1], planes[1], style="--", label=f"epoch {k}")
    ax[0, 1].set_title("2. extracted planes (supports, normals)")
    ax[0, 1].legend(fontsize=7)
    info = rel.diagnostics
    assert info is not None and info.rotation_consensus is not None
    rc, tc = info.rotation_consensus, info.translation_consensus
    rpy = np.degrees(rpy_from_rotation(info.lda.rotations))
    print(f"3. LDA: {len(info.lda.prev_pairs)} pair associations (rotation candidates)")
    sc = ax[0, 2].scatter(rpy[:, 2], rpy[:, 0], c=np.log10(rc.errors + 1e-9), s=18, cmap="viridis")
    ax[0, 2].plot(*rpy[rc.best_index, [2, 0]], "r*", ms=14, label="winner (WOCSC)")
    ax[0, 2].set(xlabel="yaw (deg)", ylabel="roll (deg)", title="3. LDA pairs: rotation candidates")
    ax[0, 2].figure.colorbar(sc, ax=ax[0, 2], label="log10 consensus error")
    ax[0, 2].legend(fontsize=7)
    print(
        f"4. consensus: rotation winner {rc.best_index} of {len(rc.errors)}, {rc.n_inliers} inliers"
    )
    for name, res, colour in (("rotation", rc, "C0"), ("translation", tc, "C1")):
        if res is not None:
            ax[1, 0].plot(
                np.sort(res.errors), ".-", color=colour, label=f"{name} ({res.n_inliers} inliers)"
            )
    ax[1, 0].set(yscale="log", xlabel="candidate (sorted)", ylabel="consensus error")
    ax[1, 0].set_title("4. consensus scores (lowest wins)")
    ax[1, 0].legend(fontsize=7)
    names = ("roll deg", "pitch deg", "yaw deg", "x cm", "y cm")
    scale = np.array([np.degrees(1)] * 3 + [100, 100])
    est, gt, sig = (
        pose5_from_transform(rel.T_prev_curr) * scale,
        pose5_from_transform(truth) * scale,
        rel.sigmas5 * scale,
    )
    rows = [
        f"{n:>9}: {e:8.3f} ± {s:6.3f}   (truth {g:8.3f})"
        for n, e, g, s in zip(names, est, gt, sig, strict=True)
    ]
    print("5. refined pose (status " + str(rel.status) + "):\n   " + "\n   ".join(rows))
    ax[1, 1].axis("off")
    ax[1, 1].text(
        0,
        0.95,
        f"5. winner, refined ({rel.status}):\n\n" + "\n".join(rows),
        va="top",
        family="monospace",
        fontsize=8,
    )
    draw_planes(ax[1, 2], planes[0], label=f"epoch {k - 1}")
    draw_planes(
        ax[1, 2], planes[1], rel.T_prev_curr, style="--", label=f"epoch {k} moved by the estimate"
    )
    ax[1, 2].set_title("6. planes of both epochs in one frame")
    ax[1, 2].legend(fontsize=7)
    for a in (ax[0, 0], ax[0, 1], ax[1, 2]):
        a.set(xlabel="x (m)", ylabel="y (m)", aspect="equal")
    return rel


def main(out: Path, epochs: int = 20, noise: str = "lms221") -> dict[str, Path]:
    """Run the walkthrough, write the pictures into ``out``; returns them by name."""
    out.mkdir(parents=True, exist_ok=True)
    config = planodom.PlanodomConfig()
    run = simulate_named(
        "paper-loop", "isoclinal", noise=noise, seed=1, n_epochs=epochs, motion="snapshot"
    )
    fig, ax = pyplot().subplots(2, 3, figsize=(16, 10), layout="constrained")
    epoch_pair(ax, run, config)
    files = {"walkthrough": save(fig, out / "walkthrough.png")}
    print(f"7. smoothing {len(run)} epochs (batch, delta <= 2)")
    sm = planodom.run_smoothing(run, config, run.rig, delta=2)
    gt = invert_transform(run.poses[0]) @ run.poses
    files["smoothing"] = plot_trajectory(
        out / "smoothing.png", sm.poses, gt, statuses=sm.odometry.statuses,
        others=[("odometry", sm.odometry.poses)], title="odometry and batch smoothing",
        label="smoothed",
    )  # fmt: skip
    for name, path in files.items():
        print(f"{name}: {path}")
    return files


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("walkthrough"))
    parser.add_argument("--epochs", type=int, default=20)
    args = parser.parse_args()
    main(args.out, args.epochs)
