"""What a smoothing run counted, for ``metrics.json`` (``planodom smooth``).

:class:`.batch.SmoothingResult` holds the graph's counts, the fixed-lag smoother's QR
fallbacks and split indefinite marginals, the loop closure's verdicts and why the
covariances are missing; :func:`smoother_metrics` writes them as plain numbers and lists,
epochs as indices (0-based, as ``epochs.csv``). All are counts of the run itself, the
same for the same input and configuration (no clock).
"""

from __future__ import annotations

from dataclasses import asdict

from planodom.smoothing.batch import SmoothingResult


def smoother_metrics(result: SmoothingResult) -> dict[str, object]:
    """The counts of ``result`` (JSON-ready: ints, floats, strings, lists, dicts).

    Keys: ``graph`` (:class:`.graph.GraphStats`: factors, landmarks, flips, gated,
    unresolved epochs), ``qr_fallback_epochs`` (the fixed-lag smoother's, in batch its
    initial guess's), ``indefinite_marginals`` (``{"epoch", "ratio"}``: ``-w_min / w_max``
    of a held marginal split at that fallback), with loop closure ``loop_matches``,
    ``loop_factors`` and ``reidentifications`` (accepted, refused), and
    ``covariance_model`` (batch: "sandwich" or "fitted", what the covariances came from)
    and ``covariance_note`` when the covariances are missing or partly undetermined (or
    fitted for want of the planes' deskewing Jacobians).
    """
    out: dict[str, object] = {"graph": asdict(result.stats)}
    out["qr_fallback_epochs"] = [int(e) for e in result.qr_fallback_epochs]
    out["indefinite_marginals"] = [
        {"epoch": int(e), "ratio": float(r)} for e, r in result.indefinite_marginals
    ]
    if result.loop_matches:
        accepted = sum(m.verdict == "accepted" for m in result.loop_matches)
        out["loop_matches"] = {"accepted": accepted, "refused": len(result.loop_matches) - accepted}
    for name, records in (
        ("loop_factors", result.loop_factors),
        ("reidentifications", result.reidentifications),
    ):
        if records:
            refused = sum(r.removed for r in records)
            out[name] = {"accepted": len(records) - refused, "refused": refused}
    if result.covariance_model:
        out["covariance_model"] = result.covariance_model
    if result.covariance_note:
        out["covariance_note"] = result.covariance_note
    return out


def fallback_warning(result: SmoothingResult) -> str | None:
    """A line for the console when the fixed-lag smoother split indefinite marginals
    (None otherwise): the run went on, and the user should know where."""
    if not result.indefinite_marginals:
        return None
    epochs = ", ".join(str(e) for e, _ in result.indefinite_marginals)
    worst = max(r for _, r in result.indefinite_marginals)
    return (
        f"the fixed-lag smoother's marginals were indefinite beyond round-off at epoch(s) "
        f"{epochs} (worst -w_min/w_max {worst:.1e}); their unobserved directions were "
        "dropped and the run went on (listed in metrics.json)"
    )
