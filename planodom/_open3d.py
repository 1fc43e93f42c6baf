"""Import open3d on machines without a system libusb.

The open3d 0.20 wheels link ``libusb-1.0.so.0`` (for RealSense support) but do not ship
it; a bare machine has no such library and ``import open3d`` fails. The
``libusb-package`` wheel ships the library: loading it into the global symbol namespace
before open3d is imported satisfies the dynamic linker, with no manual step.
"""

from __future__ import annotations

import ctypes
import sys
from typing import Any


def _preload_libusb() -> None:
    if "open3d" in sys.modules:
        return
    try:
        ctypes.CDLL("libusb-1.0.so.0", mode=ctypes.RTLD_GLOBAL)
        return  # the system has one
    except OSError:
        pass
    try:
        import libusb_package

        path = libusb_package.get_library_path()
        if path is not None:
            ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
    except (ImportError, OSError):  # pragma: no cover - open3d's own error is clearer
        pass


_preload_libusb()

import open3d  # noqa: E402

# Typed as Any: open3d's partial stubs reject the numpy arrays its functions accept.
o3d: Any = open3d

__all__ = ["o3d"]
