"""The ``planodom`` command's entry point: a Ctrl-C while it imports ends in one line."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

#: Runs the entry point as the installed script does, with a real SIGINT sent to the
#: process when it first imports numpy (well inside the command line's import: typer,
#: rich, numpy, ...), as a Ctrl-C in the first second of ``planodom run`` is.
_INTERRUPT_IN_IMPORT = """
import os, signal, sys

signal.signal(signal.SIGINT, signal.default_int_handler)  # ignored under `cmd &`

class SigintOnNumpy:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, SigintOnNumpy())
sys.argv = ["planodom", "--version"]
from planodom.entry import main
main()
"""


def test_ctrl_c_while_importing_is_one_line_and_status_130() -> None:
    """Python's KeyboardInterrupt traceback from inside numpy's import, exit -2, before."""
    out = subprocess.run(
        [sys.executable, "-c", _INTERRUPT_IN_IMPORT], capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 130, out.stderr
    assert out.stderr == "interrupted (Ctrl-C) while starting: nothing was read or written\n"
    assert out.stdout == ""


def test_the_installed_command_is_this_entry_point() -> None:
    """The script must not import the command line before the entry point runs."""
    pyproject = Path(__file__).parents[1] / "pyproject.toml"
    scripts = tomllib.loads(pyproject.read_text())["project"]["scripts"]
    assert scripts["planodom"] == "planodom.entry:main"


def test_importing_the_entry_point_imports_nothing_heavy() -> None:
    """Until its handler runs, a Ctrl-C still prints a traceback: keep that span short."""
    code = (
        "import sys; import planodom.entry; "
        "print(sorted(m for m in ('yaml', 'numpy', 'typer', 'importlib.metadata') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


#: open3d imported with a real SIGINT sent while its compiled module initialises (when it
#: imports numpy): pybind11 raises ``ImportError: initialization failed`` from the
#: KeyboardInterrupt, which a Ctrl-C 12 s into ``planodom simulate`` printed as a traceback.
_INTERRUPT_IN_OPEN3D = """
import os, signal, sys

signal.signal(signal.SIGINT, signal.default_int_handler)  # ignored under `cmd &`
from planodom.entry import interrupted_import

armed = []

class SigintInPybind:
    def find_spec(self, name, path=None, target=None):
        if name == "open3d.pybind":
            armed.append(name)
        elif len(armed) == 1:  # the next import: numpy, from the compiled init
            armed.append(name)
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, SigintInPybind())
try:
    from planodom._open3d import o3d
except ImportError as exc:
    print(type(exc.__cause__).__name__, interrupted_import(exc))
"""


def test_an_import_a_ctrl_c_cut_short_is_an_interrupt() -> None:
    out = subprocess.run(
        [sys.executable, "-c", _INTERRUPT_IN_OPEN3D], capture_output=True, text=True, timeout=300
    )
    assert out.stdout.strip() == "KeyboardInterrupt True", out.stderr[-2000:]


def test_other_import_errors_are_not_interrupts() -> None:
    from planodom.entry import interrupted_import

    try:
        raise ImportError("initialization failed") from OSError("libusb")
    except ImportError as exc:
        assert not interrupted_import(exc)
    assert not interrupted_import(ImportError("no module named x"))
    assert interrupted_import(KeyboardInterrupt())
