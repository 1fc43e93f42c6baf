"""The public API: ``import planodom`` is cheap and gives the documented, typed names."""

from __future__ import annotations

import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import planodom


def test_every_public_name_resolves_with_a_docstring() -> None:
    for name in planodom.__all__:
        value = getattr(planodom, name)
        if name == "__version__":
            assert value == version("planodom")
            continue
        doc = value.__doc__ or ""
        assert len(doc) > 60, name
    assert planodom.FixedLagSmoother is planodom.WindowedSmoother
    from planodom.odometry import PlaneOdometry

    assert planodom.PlaneOdometry is PlaneOdometry
    assert set(planodom.__all__) <= set(dir(planodom))


def test_import_is_lazy_and_typed() -> None:
    heavy = "('gtsam', 'numba', 'open3d', 'rosbags')"
    code = f"import sys, planodom; print(sorted(m for m in {heavy} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    assert (Path(planodom.__file__).parent / "py.typed").is_file()


def test_unknown_name_is_an_attribute_error() -> None:
    import pytest

    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        planodom.nothing  # noqa: B018
