"""The fused multiply-add for compiled kernels that form numpy's matrix products to the bit
(split from :mod:`planodom.odometry.planemap.register_kernels`, so that low modules such as
:mod:`planodom.se3` can use it without importing the odometry): OpenBLAS's kernels add each
product to the running sum by a fused multiply-add, in order."""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

import numba
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic


def _fma_intrinsic(typingctx, a, b, c):  # pragma: no cover - compiled
    """``a b + c`` rounded once (LLVM's ``fma``): the products of numpy's matrix products
    (OpenBLAS's kernels add each product to the running sum so, in order)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


fma = cast("Callable[[float, float, float], float]", intrinsic(_fma_intrinsic))


@numba.njit(cache=True)
def dot3(a0, a1, a2, b0, b1, b2):  # pragma: no cover - compiled
    """``a . b`` of 3-vectors as a matrix product of numpy's sums it."""
    return fma(a2, b2, fma(a1, b1, a0 * b0))
