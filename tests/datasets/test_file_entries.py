"""Dataset entries that name a file but are none (a broken symbolic link, a loop, a
directory, a FIFO): named in one line, never skipped as if absent."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from dataset_factory import make_scan, random_poses
from kitti_factory import make_sequence

from planodom.datasets import load_dataset
from planodom.datasets.dataset import write_dataset
from planodom.datasets.kitti import load_kitti_sequence
from planodom.errors import DatasetError


def _dataset(tmp_path: Path, poses: bool = True) -> Path:
    rng = np.random.default_rng(1)
    scans = [make_scan(rng, 20, ()) for _ in range(4)]
    times = 0.1 * np.arange(4)
    gt = random_poses(rng, 4) if poses else None
    write_dataset(tmp_path / "ds", scans, times, gt)
    return tmp_path / "ds"


@pytest.mark.parametrize("poses", [False, True])
@pytest.mark.parametrize("kind", ["dangling", "loop", "directory", "fifo"])
def test_a_scan_entry_that_is_no_file_is_named(tmp_path: Path, kind: str, poses: bool) -> None:
    # Without poses.tum the last scan was dropped without a word (3 epochs read of 4); with
    # it, the count differed from poses.tum's without naming the scan.
    root = _dataset(tmp_path, poses)
    entry = root / "scans" / "000003.ply"
    entry.unlink()
    if kind == "dangling":
        entry.symlink_to(tmp_path / "moved" / "000003.ply")
    elif kind == "loop":
        entry.symlink_to(entry)
    elif kind == "directory":
        entry.mkdir()
    else:
        os.mkfifo(entry)
    why = {
        "dangling": "a symbolic link that leads nowhere",
        "loop": "Too many levels of symbolic links",
        "directory": "a directory, not a file",
        "fifo": "not a regular file",
    }[kind]
    with pytest.raises(DatasetError, match=f"000003.ply: .*{why}"):
        load_dataset(root)


def test_a_symbolic_link_to_a_scan_is_read(tmp_path: Path) -> None:
    root = _dataset(tmp_path)
    entry = root / "scans" / "000003.ply"
    kept = tmp_path / "elsewhere.ply"
    shutil.move(entry, kept)
    entry.symlink_to(kept)
    assert len(load_dataset(root)) == 4


@pytest.mark.parametrize("name", ["poses.tum", "times.txt", "rig.yaml", "scans"])
def test_a_broken_link_to_a_dataset_file_is_named(tmp_path: Path, name: str) -> None:
    # poses.tum, times.txt or rig.yaml behind a broken link read as absent (no reference,
    # the default 0.1 s epochs, no rig) without a word; scans/ as "no scans/ directory"
    root = _dataset(tmp_path, poses=name != "times.txt")
    if (root / name).is_dir():
        shutil.rmtree(root / name)
    else:
        (root / name).unlink(missing_ok=True)
    (root / name).symlink_to(tmp_path / "unmounted" / name)
    with pytest.raises(DatasetError, match=f"{name}: a symbolic link that leads nowhere"):
        load_dataset(root)


@pytest.mark.parametrize("name", ["times.txt", "poses.txt"])
def test_a_broken_link_in_a_kitti_sequence_is_named(tmp_path: Path, name: str) -> None:
    seq = make_sequence(tmp_path, poses_beside=True)
    (seq / name).unlink()
    (seq / name).symlink_to(tmp_path / "unmounted" / name)
    with pytest.raises(DatasetError, match=f"{name}: a symbolic link that leads nowhere"):
        load_kitti_sequence(seq)


def test_scans_in_sub_folders_are_named(tmp_path: Path) -> None:
    # Scans written one folder per sensor (scans/front/, scans/rear/) were refused as "scans
    # is empty: no scan files", which looks wrong to whoever sees the files in there.
    root = _dataset(tmp_path)
    for sensor in ("front", "rear"):
        (root / "scans" / sensor).mkdir()
        for f in sorted((root / "scans").glob("*.ply"))[:2]:
            shutil.copy(f, root / "scans" / sensor / f.name)
    for f in (root / "scans").glob("*.ply"):
        f.unlink()
    with pytest.raises(DatasetError) as exc:
        load_dataset(root)
    assert str(exc.value).startswith(
        f"{root / 'scans'} is empty: no scan files, but its sub-folder(s) front/ (2), rear/ "
        "(2) hold scan files: a dataset reads the files in scans/ itself"
    )
    shutil.rmtree(root / "scans" / "front")
    shutil.rmtree(root / "scans" / "rear")
    with pytest.raises(DatasetError, match="is empty: no scan files$"):
        load_dataset(root)


def test_a_kitti_trees_root_names_its_sequences(tmp_path: Path) -> None:
    """Before: 'has no scans/ directory and no scan files' for dataset/ and sequences/."""
    seq = make_sequence(tmp_path, poses_beside=True)
    for root, shown in ((tmp_path / "dataset", "sequences/07"), (seq.parent, "07")):
        with pytest.raises(DatasetError) as err:
            load_dataset(root)
        assert str(err.value) == (
            f"{root} has no scans/ directory and no scan files; it holds 1 KITTI sequence "
            f"folder(s) ({shown}): give one, e.g. {seq}"
        )
    assert len(load_kitti_sequence(seq)) == 3  # which reads
