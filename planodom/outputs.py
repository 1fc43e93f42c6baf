"""Output folders written whole or not at all, never over their inputs.

A results folder (or a simulated dataset) is written into a fresh hidden sibling,
``.<name>.<pid>.<random>.partial``, and renamed into place once complete
(:func:`atomic_folder`): a run that fails or is interrupted leaves neither a half-written
folder nor an empty one (folders created for it are removed too), and an earlier folder it
was to replace is untouched until the new one is complete.

The rules, checked before anything is written:

- the output folder may not be an input, lie inside one, or contain one
  (``run DS --out DS`` would replace the dataset's ground truth by the estimate);
- an existing non-empty folder is replaced only when asked (``overwrite``), and only when
  every entry in it is one this kind of folder holds (``owned``): ``--overwrite`` on a
  folder of other files is refused rather than deleting them;
- without an output folder, results go to a fresh ``results/<timestamp>/`` and
  ``results/latest`` links to it (:func:`timestamped_folder`, :func:`link_latest`), as
  KISS-ICP does.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

from planodom.entry import interrupted_import
from planodom.errors import OutputError, OutputExistsError

LATEST = "latest"


@contextlib.contextmanager
def atomic_folder(
    target: str | Path,
    *,
    overwrite: bool = False,
    inputs: Sequence[str | Path] = (),
    owned: Callable[[Path], bool] | None = None,
    what: str = "results",
) -> Iterator[Path]:
    """Yield an empty folder to write into; on success it becomes ``target``.

    Args:
        target: the output folder (parents are created as needed, and removed again
            when the block fails).
        overwrite: replace an existing non-empty ``target``; without it that is an
            :class:`OutputExistsError`.
        inputs: files and folders the block reads: ``target`` may not be, lie in or contain
            any of them (:class:`OutputError`).
        owned: ``owned(entry) -> bool`` for each entry of an existing ``target``; an entry
            it rejects makes the overwrite an :class:`OutputError` (None: any entry). For a
            rejected folder, the message names its first file ``owned`` rejects.
        what: what the folder holds, for messages ("results", "a dataset").

    Raises:
        OutputError: naming ``target``, for the rules above, when the folder cannot be
            created (an OS error on it: below a file, no permission, ``/proc``), or when
            the disk or quota fills while the block writes (:data:`NO_SPACE`; the partial
            folder removed).
    """
    target = check_target(target, overwrite=overwrite, inputs=inputs, owned=owned, what=what)
    created = _make_parents(target)
    try:
        partial = _sibling(target, "partial")
        os.mkdir(partial)
    except OSError as exc:
        _remove_empty(created)
        raise OutputError(f"{target}: cannot create the output folder ({exc.strerror})") from None
    moved = False
    try:
        yield partial
        with _signals_held():  # a Ctrl-C between its two renames lost the earlier folder
            _move_into_place(partial, target)
            moved = True
    except BaseException as exc:
        if interrupted_import(exc):  # a Ctrl-C (or an import it cut short)
            exc.add_note(_interrupted(target, moved))
        if moved:  # the Ctrl-C held while the folder moved: it is complete
            raise
        with _signals_held():  # a second Ctrl-C left the partial folder behind
            shutil.rmtree(partial, ignore_errors=True)
            _remove_empty(created)
        if isinstance(exc, OSError) and exc.errno in NO_SPACE:
            raise OutputError(_no_space(target, partial, exc, what)) from None
        raise


def _interrupted(target: Path, moved: bool) -> str:
    """What a Ctrl-C left of the output folder ``target`` (a note on the interrupt)."""
    if moved:
        return f"{target} was written whole before it"
    kept = " (the folder there is kept as it was)" if target.exists() else ""
    return f"nothing written to {target}{kept}"


#: OS errors of a full disk or quota while writing: a file written in the partial folder
#: raises them from ``write`` or ``close``, which name no file (a traceback before).
NO_SPACE = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})


def _no_space(target: Path, partial: Path, exc: OSError, what: str) -> str:
    """The one line of a full disk: the output folder, and the file when it lies elsewhere
    (a temporary file of the run on another file system)."""
    where = ""
    if exc.filename is not None and not Path(str(exc.filename)).absolute().is_relative_to(partial):
        where = f" ({exc.filename})"
    return (
        f"{target}: cannot write {what}: {exc.strerror or exc}{where}; nothing was written "
        "(an earlier folder there is kept as it was)"
    )


def write_whole(path: str | Path, write: Callable[[Path], object]) -> None:
    """``write(tmp)`` into a hidden sibling of ``path`` with its suffix (matplotlib reads
    the format from it), then renamed over ``path``: an experiment's table or plot,
    rewritten as the experiment goes, is never left half written by a Ctrl-C or a failure;
    the earlier file stays until the new one is complete."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def check_target(
    target: str | Path,
    *,
    overwrite: bool = False,
    inputs: Sequence[str | Path] = (),
    owned: Callable[[Path], bool] | None = None,
    what: str = "results",
) -> Path:
    """The checks of :func:`atomic_folder` alone (nothing is created); returns the target
    (a symbolic link to a folder, e.g. ``results/latest``, as that folder)."""
    target = Path(target)
    if target.is_symlink() and target.is_dir():
        target = target.resolve()
    check_not_inputs(target, inputs)
    existing = _entries(target)
    # a folder of other files first: "already holds results (notes.txt); --overwrite
    # replaces it" was untrue, and --overwrite then refused it
    foreign = [target / e for e in existing if owned is not None and not owned(target / e)]
    if foreign:
        assert owned is not None
        stray = _first_foreign(foreign[0], owned).relative_to(target)
        raise OutputError(
            f"{target}: holds '{stray}', which planodom does not write as {what}; "
            "not replacing the folder (choose another output folder)"
        )
    if existing and not overwrite:
        raise OutputExistsError(target, f"{what} ({existing[0]})")
    return target


def _first_foreign(path: Path, owned: Callable[[Path], bool]) -> Path:
    """The entry to blame in a rejected folder ``path``: its first rejected file, if any."""
    if path.is_dir() and not path.is_symlink():
        for child in sorted(path.iterdir()):
            if not owned(child):
                return _first_foreign(child, owned)
    return path


def check_not_inputs(target: str | Path, inputs: Sequence[str | Path]) -> None:
    """:class:`OutputError` when ``target`` is, lies inside or contains one of ``inputs``."""
    out = Path(target).resolve()
    for given in inputs:
        path = Path(given).resolve()
        if out == path:
            relation = "is"
        elif out.is_relative_to(path):
            relation = "lies inside"
        elif path.is_relative_to(out):
            relation = "contains"
        else:
            continue
        raise OutputError(
            f"{target}: the output folder {relation} the input {given}; "
            "choose an output folder apart from the inputs"
        )


def timestamped_folder(root: str | Path = "results") -> Path:
    """A not yet existing ``root/<YYYY-MM-DD_HH-MM-SS>`` (``_2``, ``_3``... if taken)."""
    root = Path(root)
    stamp = datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    folder, n = root / stamp, 1
    while folder.exists() or folder.is_symlink():
        n += 1
        folder = root / f"{stamp}_{n}"
    return folder


def link_latest(folder: str | Path) -> Path | None:
    """Point ``<parent>/latest`` at ``folder`` (a relative symlink, replaced atomically).

    Returns the link, or None when it cannot be made (no symlinks on this file system, or
    ``latest`` is a real file or folder, which is left alone).
    """
    folder = Path(folder)
    link = folder.parent / LATEST
    if link.exists() and not link.is_symlink():
        return None
    tmp = _sibling(link, "link")
    try:
        os.symlink(folder.name, tmp)
        os.replace(tmp, link)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        return None
    return link


def _entries(target: Path) -> list[str]:
    """The names in an existing folder ``target`` ([] when it does not exist)."""
    if not target.exists():
        if target.is_symlink():
            raise OutputError(f"{target}: is a broken symbolic link")
        return []
    if not target.is_dir():
        raise OutputError(f"{target}: exists and is not a folder")
    try:
        return sorted(os.listdir(target))
    except OSError as exc:
        raise OutputError(f"{target}: cannot list the output folder ({exc.strerror})") from None


def _make_parents(target: Path) -> list[Path]:
    """Create the missing parents of ``target``; returns them, deepest last."""
    missing = []
    parent = target.absolute().parent
    while not parent.exists() and parent != parent.parent:
        missing.append(parent)
        parent = parent.parent
    created: list[Path] = []
    for folder in reversed(missing):
        try:
            os.mkdir(folder)
        except OSError as exc:
            _remove_empty(created)
            raise OutputError(
                f"{target}: cannot create the output folder ({folder}: {exc.strerror})"
            ) from None
        created.append(folder)
    return created


def _remove_empty(folders: list[Path]) -> None:
    for folder in reversed(folders):
        with contextlib.suppress(OSError):
            os.rmdir(folder)


def _sibling(target: Path, kind: str) -> Path:
    """A fresh hidden name beside ``target``: ``.<name>.<pid>.<random>.<kind>``."""
    name = f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}.{kind}"
    return target.absolute().parent / name


def _move_into_place(partial: Path, target: Path) -> None:
    """Rename ``partial`` to ``target``, replacing what is there (checked beforehand)."""
    if not target.exists():
        os.rename(partial, target)
        return
    if not os.listdir(target):
        os.rmdir(target)
        os.rename(partial, target)
        return
    old = _sibling(target, "old")
    os.rename(target, old)
    try:
        os.rename(partial, target)
    except OSError:
        os.rename(old, target)  # put the earlier folder back
        raise
    shutil.rmtree(old, ignore_errors=True)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold Ctrl-C and the :data:`TERMINATING` signals whose handler is Python's while the
    block runs, and run the handler of the first that came after it, so that a folder
    being moved into place is not left half moved. (Blocking them with ``pthread_sigmask``
    does not hold them: the kernel hands the signal to another thread, numpy's or
    open3d's, and Python raises in the main thread all the same.) Main thread only, as
    signal handlers are; elsewhere nothing is held."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[tuple[signal.Signals, Any]] = []
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, *TERMINATING)}
    held = {sig: handler for sig, handler in handlers.items() if callable(handler)}
    for sig in held:
        signal.signal(sig, lambda signum, frame: came.append((signal.Signals(signum), frame)))
    try:
        yield
    finally:
        for sig, handler in held.items():
            signal.signal(sig, handler)
        if came:
            signum, frame = came[0]
            held[signum](signum, frame)  # e.g. KeyboardInterrupt, now


#: Signals that end a run as Ctrl-C does: a scheduler's or ``timeout``'s SIGTERM, a closed
#: terminal's SIGHUP. Their default action killed the process in place, leaving its
#: hidden ``.<name>.<pid>.<random>.partial`` folder behind.
TERMINATING = (signal.SIGTERM, signal.SIGHUP)


def exit_on_termination() -> None:
    """Make :data:`TERMINATING` signals raise ``SystemExit(128 + signal)`` (the shell's
    status of a process they kill), so that :func:`atomic_folder` removes its partial
    folder. A signal whose action is not the default (``nohup`` ignores SIGHUP) is left
    as it is. Main thread only (Python's rule for signal handlers)."""

    def _exit(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    for sig in TERMINATING:
        if signal.getsignal(sig) is signal.SIG_DFL:
            signal.signal(sig, _exit)
