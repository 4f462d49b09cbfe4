"""The temporal figures of several methods as a report section: a JSON-ready dict and a Markdown table."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from torchmeshmetric.temporal.figures import FIGURE_NAMES, TemporalFigures

__all__ = ["FIGURE_LABELS", "temporal_markdown", "temporal_report"]

#: How the tables and the ``temporal`` command label each of :data:`FIGURE_NAMES`.
FIGURE_LABELS = {"kg": "KG (%)", "kso": "KSO (E_RMS)", "sted_s": "STED_s", "sted_t": "STED_t", "sted": "STED"}


def temporal_report(figures: Mapping[str, TemporalFigures]) -> dict[str, dict[str, Any]]:
    """``{method: {figure: value, "registered": bool, ...}}`` (the reports' ``"temporal"`` entry).

    Example:
        >>> f = TemporalFigures(1.0, 2.0, 0.1, 0.2, 0.1, True, 3, 100)
        >>> row = temporal_report({"qem": f}).get("qem", {})
        >>> row.get("kg"), row.get("registered")
        (1.0, True)
    """
    return {name: f.as_dict() for name, f in figures.items()}


def temporal_markdown(figures: Mapping[str, TemporalFigures]) -> str:
    """A Markdown section with one row per method: KG, KSO, STED_s, STED_t, STED and the form used.

    Example:
        >>> f = TemporalFigures(1.0, 2.0, 0.1, 0.2, 0.1, True, 3, 100)
        >>> print(temporal_markdown({"qem": f}).splitlines()[4])
        | qem | 1 | 2 | 0.1 | 0.2 | 0.1 | registered |
    """
    lines = [
        "## Temporal metrics (KG, KSO, STED; docs/temporal.md)",
        "",
        "| method | " + " | ".join(FIGURE_LABELS[k] for k in FIGURE_NAMES) + " | form |",
        "|---|" + "---:|" * len(FIGURE_NAMES) + "---|",
    ]
    for name, f in figures.items():
        cells = " | ".join(f"{float(getattr(f, k)):.6g}" for k in FIGURE_NAMES)
        lines.append(f"| {name} | {cells} | {'registered' if f.registered else 'exact'} |")
    # The methods share the original's tracking, hence its registrations.
    unconverged = sorted({k for f in figures.values() for k in f.unconverged})
    if unconverged:
        lines += ["", unconverged_tracking_note(unconverged)]
    return "\n".join(lines) + "\n"


def unconverged_tracking_note(frames: Sequence[int]) -> str:
    """The line that names the original's frame pairs whose registration, which the tracking follows, failed.

    Example:
        >>> unconverged_tracking_note([2])[:60]
        'Registration not converged for frame pair 1 -> 2 of the orig'
    """
    pairs = ", ".join(f"{k - 1} -> {k}" for k in frames)
    several = len(frames) > 1
    return (
        f"Registration not converged for frame pair{'s' if several else ''} {pairs} of the original: the registered "
        f"forms follow frame 0 through {'them' if several else 'it'} (docs/registration.md)."
    )
