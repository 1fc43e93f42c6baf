"""The batch's linear steps: gtsam's Cholesky, multifrontal, then sequential, then QR.

Why a sequential Cholesky before QR (issue 14, QRGATE). gtsam (4.3, its "normalised
all-pivot" check) refuses a dense Cholesky of a clique's frontal block when a pivot keeps
less than 2^-24 of that variable's diagonal *as the block was assembled*:
``R_ii^2 < 2^-24 A_ii``. In a multifrontal elimination a clique's frontal block holds
several variables at once, so a variable eliminated after a strongly coupled one is judged
against a diagonal that the coupling, not the variable's own determination, made large.
On the 2 000-epoch lap with loops (world 0, 6 mm) that is an anchored landmark in the root
clique: at the loop gate's re-solve start (the initial guess) the Cauchy kernel
down-weights every observation of plane ``L(161)`` but the one of its anchor epoch (whose
residual is zero: the landmark was initialised from it), so one plane factor
``(X(905), A(161), L(161))`` with singular values 1.8e5 makes the plane offset's diagonal
2.6e8, of which 9.3 is left once ``X(905)`` and ``A(161)`` are eliminated before it in the
same block: 3.6e-8 < 2^-24 = 6.0e-8. Nothing is undetermined: QR's smallest pivot there
is 3.05, LAPACK's Cholesky of the same assembled block succeeds, and the root clique's
exact marginal has condition number 4e5 (of R). A sequential elimination (one variable a
step) assembles each variable's block after the Schur updates of those before it, so the
same test compares the pivot with what is left of the diagonal, and passes; it is the same
Cholesky in another grouping (there 0.08 s, QR's multifrontal 0.59 s; the steps equal to
1.5e-9 of a unit step). QR stays the last resort (an undetermined or truly singular system).
"""

from __future__ import annotations

import gtsam


def solve(linear: gtsam.GaussianFactorGraph, ordering: gtsam.Ordering) -> gtsam.VectorValues:
    """The least-squares solution of ``linear`` (whitened Jacobian factors) eliminated in
    ``ordering``: gtsam's multifrontal Cholesky; when gtsam finds a clique indeterminant, a
    sequential Cholesky in the same ordering; when that fails too, multifrontal QR."""
    return solve_step(linear, ordering)[0]


def solve_step(
    linear: gtsam.GaussianFactorGraph, ordering: gtsam.Ordering, multifrontal: bool = True
) -> tuple[gtsam.VectorValues, bool]:
    """:func:`solve`, and whether the multifrontal Cholesky was refused; with
    ``multifrontal`` False it is not tried (``smoothing.sequential_after_refusal``: the
    rest of a Levenberg-Marquardt call after a refusal; there each later step of the 2 000-
    epoch lap's gate re-solves was refused too, 0.094 s wasted a step, BATCH15)."""
    if multifrontal:
        try:
            return linear.optimize(ordering), False
        except RuntimeError:
            pass
    try:
        return linear.eliminateSequential(ordering).optimize(), True
    except RuntimeError:
        return linear.optimize(ordering, gtsam.EliminateQR), True
