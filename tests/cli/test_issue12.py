"""Every case of issue 12 through the command line: a one-line error (exit status 2,
naming the file or field) or the right result, and never a lost input or earlier result."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml
from cli_checks import fails
from typer.testing import CliRunner

from planodom.cli import app
from planodom.datasets import read_scan, write_scan

runner = CliRunner()


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("sim") / "ds"
    result = runner.invoke(app, ["simulate", "--out", str(path), "--epochs", "5"])
    assert result.exit_code == 0, result.output
    return path


@pytest.fixture
def ds(simulated: Path, tmp_path: Path) -> Path:
    shutil.copytree(simulated, tmp_path / "ds")
    return tmp_path / "ds"


def ok(args: list[str]) -> None:
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


# --------------------------------------------------------------------------- lost data


def test_out_equal_to_or_inside_the_dataset_is_refused(ds: Path) -> None:
    before = _snapshot(ds)
    fails(["run", ds, "--out", ds], str(ds), "is the input")
    fails(["run", ds, "--out", ds / "scans", "--overwrite"], "lies inside the input")
    fails(["smooth", ds, "--out", ds.parent, "--overwrite"], "contains the input")
    assert _snapshot(ds) == before


def test_earlier_results_are_kept_unless_overwrite_then_replaced_whole(ds: Path) -> None:
    out = ds.parent / "res"
    ok(["smooth", ds, "--out", out, "--delta", "2"])
    assert (out / "odometry.tum").exists()
    before = _snapshot(out)
    fails(["run", ds, "--out", out], str(out), "already holds results", "--overwrite")
    assert _snapshot(out) == before
    ok(["run", ds, "--out", out, "--overwrite"])
    assert not (out / "odometry.tum").exists()  # no stale file beside the new poses.tum
    (out / "notes.txt").write_text("mine")
    fails(["run", ds, "--out", out, "--overwrite"], "notes.txt", "does not write")
    assert (out / "notes.txt").read_text() == "mine"


def test_scenario_does_not_replace_an_existing_dataset(tmp_path: Path) -> None:
    (tmp_path / "out" / "dataset").mkdir(parents=True)
    (tmp_path / "out" / "dataset" / "poses.tum").write_text("# mine\n")
    args = ["run", "--scenario", "paper-loop", "--epochs", "3", "--out", tmp_path / "out"]
    fails(args, "already holds results", "--overwrite")
    assert (tmp_path / "out" / "dataset" / "poses.tum").read_text() == "# mine\n"


def test_simulate_overwrite_checks_before_deleting(ds: Path) -> None:
    (ds / "scans" / "notes.txt").write_text("stray")
    before = _snapshot(ds)
    fails(["simulate", "--out", ds, "--epochs", "3", "--overwrite"], str(ds), "scans/notes.txt")
    assert _snapshot(ds) == before
    (ds / "scans" / "notes.txt").unlink()
    ok(["simulate", "--out", ds, "--epochs", "3", "--overwrite"])
    assert len(list((ds / "scans").iterdir())) == 3


def test_simulate_points_at_the_option(ds: Path) -> None:
    fails(["simulate", "--out", ds, "--epochs", "3"], "--overwrite", absent=("overwrite=True",))


def test_default_out_is_a_fresh_timestamped_folder_with_latest(
    ds: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    ok(["run", ds])
    ok(["run", ds])
    runs = sorted(p for p in (tmp_path / "results").iterdir() if not p.is_symlink())
    assert len(runs) == 2 and all((r / "poses.tum").exists() for r in runs)
    assert (tmp_path / "results" / "latest").resolve() == runs[-1].resolve()


# --------------------------------------------------------------------------- scan files


def _as_pcd(ds: Path) -> list[Path]:
    for ply in sorted((ds / "scans").iterdir()):
        write_scan(ply.with_suffix(".pcd"), read_scan(ply))
        ply.unlink()
    return sorted((ds / "scans").iterdir())


def _ascii_pcd(n_header: int, rows: list[str]) -> str:
    return (
        "VERSION 0.7\nFIELDS x y z ring\nSIZE 4 4 4 2\nTYPE F F F U\nCOUNT 1 1 1 1\n"
        f"WIDTH {n_header}\nHEIGHT 1\nPOINTS {n_header}\nDATA ascii\n" + "".join(rows)
    )


@pytest.mark.parametrize(
    "rows, header, where",
    [
        (["1 2 3 0\n", "4 5 0\n", "7 8 9 1\n"], 3, ":11: 3 values"),  # a short line
        (["1 2 3 0\n", "foo bar baz 0\n", "7 8 9 1\n"], 3, ":11: 'foo'"),  # not numbers
        ([f"{k} 1 2 0\n" for k in range(1000)], 100, "1000 point lines, its header POINTS 100"),
    ],
)
def test_ascii_pcd_is_never_guessed(ds: Path, rows: list[str], header: int, where: str) -> None:
    files = _as_pcd(ds)
    files[2].write_text(_ascii_pcd(header, rows))
    fails(["run", ds, "--out", ds.parent / "o"], f"{files[2]}", where)
    assert not (ds.parent / "o").exists()


def test_binary_pcd_with_too_small_a_count(ds: Path) -> None:
    files = _as_pcd(ds)
    data = files[2].read_bytes()
    n = len(read_scan(files[2]))
    data = data.replace(f"WIDTH {n}\n".encode(), b"WIDTH 100\n")
    files[2].write_bytes(data.replace(f"POINTS {n}\n".encode(), b"POINTS 100\n"))
    fails(["run", ds, "--out", ds.parent / "o"], f"{files[2]}", "longer than its header")


def test_gap_in_numbering_without_poses(ds: Path) -> None:
    (ds / "scans" / "000002.ply").unlink()
    (ds / "poses.tum").unlink()
    fails(["run", ds, "--out", ds.parent / "o"], "000003.ply", "1 scan(s) missing", "poses.tum")


def test_scan_values_name_the_file(ds: Path) -> None:
    scan = read_scan(ds / "scans" / "000001.ply")
    far = scan.points.copy()
    far[0, 0] = 1e30
    write_scan(ds / "scans" / "000001.ply", type(scan)(far, scan.ring, scan.t, scan.label))
    fails(["run", ds, "--out", ds.parent / "o"], "000001.ply", "1e+30")
    rig = yaml.safe_load((ds / "rig.yaml").read_text())
    rig["sensor_origins"] = rig["sensor_origins"][:1] * 2  # two rings only
    (ds / "rig.yaml").write_text(yaml.safe_dump(rig))
    write_scan(ds / "scans" / "000001.ply", scan)
    fails(["run", ds, "--out", ds.parent / "o"], "000000.ply", "ring ids", "rig.yaml")


def _unreadable(monkeypatch: pytest.MonkeyPatch, file: Path) -> None:
    """``file`` cannot be read from now on (as if its permissions changed mid-run)."""
    real = Path.read_bytes

    def read_bytes(self: Path) -> bytes:
        if self == file:
            raise PermissionError(13, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", read_bytes)


def test_scan_unreadable_mid_run(ds: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = ds.parent / "o"
    ok(["run", ds, "--out", out])
    before = _snapshot(out)
    _unreadable(monkeypatch, ds / "scans" / "000003.ply")
    fails(["run", ds, "--out", out, "--overwrite"], "000003.ply", "Permission denied")
    assert _snapshot(out) == before  # the earlier results are untouched
    assert [p.name for p in ds.parent.iterdir() if p.name.startswith(".")] == []
    ok(["run", ds, "--out", out, "--overwrite", "--skip-bad-scans"])
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["skipped_scans"] == [str(ds / "scans" / "000003.ply")]
    rows = (out / "epochs.csv").read_text().splitlines()
    assert len(rows) == 6 and ",unresolved," in rows[4]


def test_first_scan_unreadable_is_skipped_once(ds: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The first scan is read twice (a probe, then its epoch): it was warned of, counted
    and listed in metrics.json twice."""
    out = ds.parent / "o"
    _unreadable(monkeypatch, ds / "scans" / "000000.ply")
    ok(["run", ds, "--out", out, "--skip-bad-scans"])
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["skipped_scans"] == [str(ds / "scans" / "000000.ply")]


# --------------------------------------------------------------------------- config and rig


@pytest.mark.parametrize(
    "text, field",
    [
        ("extraction: {tolerance_floor_m: -1}", "tolerance_floor_m"),
        ("extraction: {range_noise_m: .nan}", "range_noise_m"),
        ("extraction: {ransac_iterations: 0}", "ransac_iterations"),
        ("extraction: {max_planes: -3}", "max_planes"),
        ("extraction: {voxel_size_m: 0}", "voxel_size_m"),
        ("extraction: {mode: banana}", "extraction.mode"),
    ],
)
def test_config_values_checked_at_load(ds: Path, text: str, field: str) -> None:
    (ds.parent / "c.yaml").write_text(text + "\n")
    out = ds.parent / "o"
    fails(["run", ds, "--out", out, "--config", ds.parent / "c.yaml"], "c.yaml", field)
    assert not out.exists()


def test_binary_config(ds: Path) -> None:
    (ds.parent / "c.yaml").write_bytes(bytes(range(256)))
    fails(["run", ds, "--out", ds.parent / "o", "--config", ds.parent / "c.yaml"], "c.yaml")
    fails(["config", "--config", ds.parent / "c.yaml"], "c.yaml")


@pytest.mark.parametrize(
    "key, value",
    [
        ("motion_bounds", "fast"),
        ("motion_bounds", {"max_translation_m": -2}),
        ("sensor_origins", [[1.0, 2.0]]),
        ("sensor_origins", "left"),
        ("platform", "car"),
    ],
)
def test_rig_values_checked_at_load(ds: Path, key: str, value: object) -> None:
    rig = yaml.safe_load((ds / "rig.yaml").read_text())
    rig[key] = value
    (ds / "rig.yaml").write_text(yaml.safe_dump(rig))
    fails(["run", ds, "--out", ds.parent / "o"], "rig.yaml", key)


# --------------------------------------------------------------------------- trajectories


def test_huge_tum_values_blame_the_input(ds: Path) -> None:
    lines = (ds / "poses.tum").read_text().splitlines()
    tokens = lines[3].split()
    tokens[1] = "1e300"
    lines[3] = " ".join(tokens)
    (ds / "poses.tum").write_text("\n".join(lines) + "\n")
    out = ds.parent / "o"
    fails(["run", ds, "--out", out], f"{ds / 'poses.tum'}:4", "position", absent=(str(out),))
    fails(["eval", ds / "poses.tum", ds / "poses.tum"], "poses.tum:4")


def test_delta_errors_speak_of_delta(ds: Path) -> None:
    fails(["eval", ds / "poses.tum", ds, "--delta", "1000"], "--delta 1000")
    out = ds.parent / "o"
    fails(["smooth", ds, "--out", out, "--delta", "1000"], "--delta 1000", absent=("window",))
    fails(["smooth", ds, "--out", out, "--delta", "3", "--window", "3"], "--delta 3", "window")
    # --window alone named the config field smoothing.window, not the option
    fails(["smooth", ds, "--out", out, "--window", "3"], "--window 3", "D = 3", "--delta")
    assert not out.exists()


# --------------------------------------------------------------------------- output paths


def test_out_that_cannot_be_created(ds: Path) -> None:
    fails(["run", ds, "--out", "/proc/x"], "/proc/x", "cannot create")
    (ds.parent / "file").write_text("")
    fails(["run", ds, "--out", ds.parent / "file" / "o"], str(ds.parent / "file" / "o"))
    fails(["simulate", "--out", ds.parent / "file" / "o", "--epochs", "2"], "file")


def test_a_real_bug_keeps_its_traceback(ds: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import planodom.odometry

    def broken(*args: object, **kwargs: object) -> None:
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(planodom.odometry, "run_odometry", broken)
    result = runner.invoke(app, ["run", str(ds), "--out", str(ds.parent / "o")])
    assert result.exit_code == 1 and isinstance(result.exception, ZeroDivisionError)
    assert not (ds.parent / "o").exists()


def test_run_refuses_a_delta_no_epoch_can_use(ds: Path) -> None:
    """--delta 50 on 5 epochs ran, every epoch associated with the first under bounds
    widened 50-fold; smooth refused it already."""
    out = ds.parent / "out"
    fails(["run", ds, "--out", out, "--delta", "50"], "--delta 50", "delta < 5")
    (ds.parent / "c.yaml").write_text("odometry: {delta: 5}\n")
    fails(["run", ds, "--out", out, "--config", ds.parent / "c.yaml"], "odometry.delta 5")
    assert not out.exists()


def test_points_beyond_any_sensor_range_are_reported(ds: Path) -> None:
    """Scans 5e5 m from the base origin (a map-frame export) ran with every epoch
    unresolved and no word why."""
    for path in sorted((ds / "scans").iterdir()):
        scan = read_scan(path)
        write_scan(path, type(scan)(scan.points + [5e5, 0.0, 0.0], scan.ring, scan.t))
    out = ds.parent / "out"
    result = runner.invoke(app, ["run", str(ds), "--out", str(out)])
    assert result.exit_code == 0, result.output
    warning = [line for line in result.stderr.splitlines() if "1000 m" in line]
    assert len(warning) == 1 and "000000" in warning[0] and "of" in warning[0], result.stderr
    listed = json.loads((out / "metrics.json").read_text())["scans_beyond_sensor_range"]
    assert len(listed) == len(list((ds / "scans").iterdir()))


def test_the_same_run_twice_writes_the_same_bytes(ds: Path) -> None:
    """Everything but timing.json (the clock's speed): metrics.json held the speed."""
    for name in ("a", "b"):
        ok(["run", ds, "--out", ds.parent / name])
    a, b = _snapshot(ds.parent / "a"), _snapshot(ds.parent / "b")
    assert set(a) == set(b) and "timing.json" in a and "metrics.json" in a
    assert [k for k in a if a[k] != b[k] and k != "timing.json"] == []


def test_simulate_refuses_epochs_that_cannot_fit_in_memory(tmp_path: Path) -> None:
    """--epochs 10**12 failed after a while with a MemoryError traceback."""
    out = tmp_path / "sim"
    fails(["simulate", "--out", out, "--epochs", 10**12], "--epochs 1000000000000", "GB")
    assert not out.exists()


def test_scans_without_points_are_reported(ds: Path) -> None:
    """An empty scan made an unresolved epoch that nothing named."""
    import numpy as np

    from planodom.scan import Scan

    empty = Scan(np.zeros((0, 3)), np.zeros(0, np.int32), np.zeros(0))
    write_scan(sorted((ds / "scans").iterdir())[2], empty)
    out = ds.parent / "out"
    result = runner.invoke(app, ["run", str(ds), "--out", str(out)])
    assert result.exit_code == 0, result.output
    warning = [line for line in result.stderr.splitlines() if "hold no points" in line]
    assert len(warning) == 1 and "000002" in warning[0], result.stderr
    listed = json.loads((out / "metrics.json").read_text())["scans_without_points"]
    assert [Path(p).name for p in listed] == [sorted((ds / "scans").iterdir())[2].name]


def test_repeated_scans_are_reported(ds: Path) -> None:
    """A scan file that repeats the one before it (a frozen driver's frame, written again)
    made its epoch measure no motion, without a word (20 epochs of a random world with two
    such files: ATE 0.06 m -> 0.54 m)."""
    files = sorted((ds / "scans").iterdir())
    shutil.copy(files[2], files[3])
    out = ds.parent / "out"
    result = runner.invoke(app, ["run", str(ds), "--out", str(out)])
    assert result.exit_code == 0, result.output
    warning = [line for line in result.stderr.splitlines() if "point for point" in line]
    assert len(warning) == 1, result.stderr
    assert f"(first: {files[3]}, as {files[2]})" in " ".join(result.stderr.split())
    listed = json.loads((out / "metrics.json").read_text())["scans_repeated"]
    assert listed == [str(files[3])]


def test_scans_in_millimetres_are_named_as_such(ds: Path) -> None:
    """float millimetres were warned of as 'a map-frame export?': a scan that itself spans
    more than twice any sensor's range is no metres at all."""
    for path in sorted((ds / "scans").iterdir()):
        scan = read_scan(path)
        write_scan(path, type(scan)(scan.points * 1000.0, scan.ring, scan.t))
    result = runner.invoke(app, ["run", str(ds), "--out", str(ds.parent / "out")])
    assert result.exit_code == 0, result.output
    warning = [line for line in result.stderr.splitlines() if "1000 m" in line]
    assert len(warning) == 1 and "not metres (millimetres?" in warning[0], result.stderr
    assert "map-frame" not in warning[0]
