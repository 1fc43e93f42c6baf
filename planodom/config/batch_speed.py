"""Configuration of how the batch smoothing spends its time, not what it computes (a part of
:class:`~planodom.config.smoothing.SmoothingConfig`; issue 14's 2 000-epoch target)."""

from __future__ import annotations

from planodom.config.section import Section


class BatchSpeedConfig(Section):
    """Where the batch's work runs; fields of the ``smoothing`` section."""

    batch_initial_concurrent: bool = False
    """Batch with ``batch_initial`` "windowed": run the fixed-lag smoother that gives the
    initial guess in a forked child process while this process builds the graph epoch by
    epoch; each pose is handed over once it has left the window (its value final), and the
    graph's construction waits only where it needs a pose not yet sent
    (planodom.smoothing.initial_ahead). The same poses, covariances and loop closures bit
    for bit; less wall time where a second core is free, about as much CPU time (the child's
    and the parent's together). Needs ``os.fork`` (POSIX); "checked" and "odometry" run as
    before. Off by default: on the 2 000-epoch lap with loops 53.5 -> 37.6 s of wall time at
    load 2.5, but slower in 3 of 6 pairs at load 3-6, where no core is free
    (docs/RESULTS.md, BATCH16)."""
    sequential_after_refusal: bool = False
    """Batch Levenberg-Marquardt (the loop start's and the loop gate's solves): once gtsam
    refuses a multifrontal Cholesky step (its clique pivot test, planodom.smoothing.
    linear_solve), the rest of that solve's steps go straight to the sequential Cholesky
    instead of trying the multifrontal one first. The same Cholesky in another grouping:
    not the same bits where a later step would have factored multifrontally (round-off
    apart). Off by default: bit-identical on 11 lap-noises and the 2 000-epoch lap, whose
    linear steps it takes from 9.68 to 8.91 s of CPU, 2 % of the batch (docs/RESULTS.md,
    BATCH16)."""
