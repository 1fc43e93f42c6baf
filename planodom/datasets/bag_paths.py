"""Where a bag is: a ROS 1 ``.bag`` file or a ROS 2 folder, and a recording left unclosed."""

from __future__ import annotations

import re
from pathlib import Path

from planodom.errors import DatasetError

#: The last bytes of a closed (complete) mcap file.
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: The first bytes of an SQLite 3 database file.
SQLITE_MAGIC = b"SQLite format 3\x00"
STORAGE_SUFFIXES = (".db3", ".mcap")
#: Their names compressed whole (``ros2 bag record --compression-mode file``).
ZSTD_NAMES = (".db3.zstd", ".mcap.zstd")


def is_bag(path: str | Path) -> bool:
    """True for a ROS 1 ``.bag`` file, a ROS 2 bag (a folder with ``metadata.yaml``) or a
    ROS 2 storage file read alone (:func:`is_storage_file`)."""
    path = Path(path)
    if path.is_file():
        return path.suffix == ".bag" or is_storage_file(path)
    return path.is_dir() and (path / "metadata.yaml").is_file()


def is_bag_part(path: str | Path) -> bool:
    """True for a storage file of a ROS 2 bag folder (``.db3``, ``.mcap``, or either
    compressed whole as ``.zstd``) or its ``metadata.yaml``: the folder is the bag it
    stands for (a ``metadata.yaml`` given was "not a directory")."""
    path = Path(path)
    names = (*STORAGE_SUFFIXES, *ZSTD_NAMES)
    part = path.name.endswith(names) or path.name == "metadata.yaml"
    return path.is_file() and part and is_bag(path.parent)


def is_storage_file(path: str | Path) -> bool:
    """True for a complete ROS 2 storage file without a ``metadata.yaml`` beside it, which
    rosbags reads alone (an mcap file as Foxglove or the mcap tool record it, a bag's
    ``.db3`` or ``.mcap`` copied by itself): an ``.mcap`` with mcap's magic at both ends (a
    recording not closed lacks the end one) or a ``.db3`` with SQLite's header."""
    path = Path(path)
    if not path.is_file() or path.suffix not in STORAGE_SUFFIXES:
        return False
    if (path.parent / "metadata.yaml").is_file():
        return False  # a file of a ROS 2 bag folder: the folder is the bag
    magic = MCAP_MAGIC if path.suffix == ".mcap" else SQLITE_MAGIC
    with open(path, "rb") as f:
        head = f.read(len(magic))
        if path.suffix == ".mcap":
            f.seek(max(path.stat().st_size - len(magic), len(magic)))
            head += f.read()
    return head == magic * (2 if path.suffix == ".mcap" else 1)


def unfinished_bag(path: str | Path) -> str | None:
    """Why ``path`` looks like a bag whose recording was not closed, or None: a ROS 1
    ``.bag.active`` file (no index yet) or ROS 2 storage files without ``metadata.yaml``
    (written when the recorder closes); the reader needs what closing writes."""
    path = Path(path)
    if path.is_file() and path.name.endswith(".bag.active"):
        return (
            f"{path} is an unfinished ROS 1 recording (.bag.active: the recorder was not "
            "closed, the bag has no index): `rosbag reindex` it and rename it to .bag"
        )
    if path.is_file() and path.name.endswith(ZSTD_NAMES):
        return (
            f"{path} is a ROS 2 storage file compressed whole (zstd) without its bag's "
            f"metadata.yaml: `zstd -d` it and give the {path.suffixes[-2]} file"
        )
    folder = path.parent if path.is_file() and path.suffix in STORAGE_SUFFIXES else path
    storage = folder.is_dir() and (any(folder.glob("*.db3")) or any(folder.glob("*.mcap")))
    if storage and not (folder / "metadata.yaml").is_file():
        files = sorted(p for p in folder.iterdir() if p.suffix in STORAGE_SUFFIXES)
        alone = (
            f", or give {files[0].name} itself (read alone)"
            if len(files) == 1 and is_storage_file(files[0])
            else ""
        )
        return (
            f"{folder} holds ROS 2 bag storage (.db3 / .mcap) but no metadata.yaml (the "
            f"recorder was not closed?): `ros2 bag reindex {folder}` writes it{alone}"
        )
    return None


def bag_location(path: str | Path) -> Path:
    """The path rosbags opens: the ``.bag`` file or the ROS 2 folder (also from its file)."""
    path = Path(path)
    if not path.exists():
        raise DatasetError(f"bag {path} does not exist")
    if is_bag_part(path):
        return path.parent
    if not is_bag(path):
        raise DatasetError(
            unfinished_bag(path)
            or f"{path} is not a bag: neither a ROS 1 .bag file nor a ROS 2 bag folder with "
            "metadata.yaml"
        )
    return path


def split_parts_note(path: Path) -> list[str]:
    """The note on the other parts of a split ROS 1 recording beside ``path`` (``NAME_0.bag``,
    ``NAME_1.bag``, ... as ``rosbag record --split`` names them: numbered from 0 without a
    hole), or none: one part is read alone, so the user should know the rest lies beside it.
    For a ROS 2 storage file read alone, the note on the other storage files beside it."""
    if is_storage_file(path):
        return _storage_siblings_note(path)
    found = re.fullmatch(r"(.+)_(\d+)\.bag", path.name)
    if not path.is_file() or found is None:
        return []
    prefix = found.group(1)
    named = re.compile(rf"{re.escape(prefix)}_(\d+)\.bag")
    number = {
        p.name: int(m.group(1)) for p in path.parent.iterdir() if (m := named.fullmatch(p.name))
    }
    order = sorted(number, key=number.__getitem__)
    if len(order) < 2 or sorted(number.values()) != list(range(len(order))):
        return []  # rosbag numbers the parts 0, 1, 2, ...: run_1.bag, run_2.bag are runs
    others = [name for name in order if name != path.name]
    shown = ", ".join(others[:5]) + (f", ... ({len(others)} in all)" if len(others) > 5 else "")
    src = " ".join(order if len(order) <= 5 else [*order[:2], "...", order[-1]])
    return [
        f"{shown} beside {path.name}: parts of one split recording? Only {path.name} is "
        f"read; `rosbags-convert --src {src} --dst {prefix}.bag` merges them into one bag"
    ]


def _storage_siblings_note(path: Path) -> list[str]:
    """The note on the storage files of ``path``'s kind beside it (a ROS 2 split recording
    whose ``metadata.yaml``, which lists the parts, is missing), or none."""
    others = sorted(p.name for p in path.parent.glob(f"*{path.suffix}") if p != path)
    if not others:
        return []
    shown = ", ".join(others[:5]) + (f", ... ({len(others)} in all)" if len(others) > 5 else "")
    return [
        f"{shown} beside {path.name}: parts of one split recording? Only {path.name} is read "
        f"(no metadata.yaml lists the parts); `ros2 bag reindex {path.parent}` writes one, "
        "then give the folder"
    ]
