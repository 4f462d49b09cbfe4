"""The temporal figures of several methods as a report section: a JSON-ready dict and a Markdown table."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from torchmeshmetric._format import format_number, markdown_cell
from torchmeshmetric.temporal.figures import FIGURE_NAMES, TemporalFigures

if TYPE_CHECKING:
    from torchmeshmetric.evaluation.determinacy import Determinacy

__all__ = [
    "FIGURE_DIGITS_NOTE",
    "FIGURE_FORMATS",
    "FIGURE_LABELS",
    "format_figure",
    "temporal_determinacy_note",
    "temporal_markdown",
    "temporal_report",
]

#: How the tables and the ``temporal`` command label each of :data:`FIGURE_NAMES`.
FIGURE_LABELS = {"kg": "KG (%)", "kso": "KSO (E_RMS)", "sted_s": "STED_s", "sted_t": "STED_t", "sted": "STED"}

#: Printed format of each figure, by form (``False``: exact, ``True``: registered): only the digits the input
#: determines. Measured (tests/temporal/temporal_determinacy.py, docs/temporal.md "Which digits the input
#: determines"): rounding the built-in frames (~20k vertices, 4 to 10 frames) from float64 to float32 moves the
#: exact forms' KG, KSO and STED_t by at most 2.4e-7 (relative) and their STED_s by 3.9e-4 (the relative length
#: changes of very short edges); rounding them to float32 or to 6 decimals moves the registered forms' KG, KSO and
#: STED_t by up to 4.1e-4 and their STED_s by 1.1e-3 (2026-12-07; 6 decimals set these, float32 alone moves them by
#: 4.5e-5 and 4.2e-4: the registrations and the tracking amplify the rounding, as they do the paper's statistics).
#: Hence 6 / 3 and 3 / 2 significant digits (``floor(-log10(change))``, the tables' rule). The registered forms'
#: registrations draw independently of how the original frames are stored (``sampling="canonical"``): 3 other orders
#: (:func:`~torchmeshmetric.evaluation.determinacy.relabel_frames`) of the demo at resolutions 160 and 24 (3 frames,
#: QEM 50 %) moved them by at most 3e-12 (relative; with the index draws, ``{"sampling": "index"}``: 1.8e-3 and
#: 5.6e-3, docs/temporal.md). The JSON keeps every digit.
FIGURE_FORMATS: dict[bool, dict[str, str]] = {
    False: {"kg": "#.6g", "kso": "#.6g", "sted_s": "#.3g", "sted_t": "#.6g", "sted": "#.3g"},
    True: {"kg": "#.3g", "kso": "#.3g", "sted_s": "#.2g", "sted_t": "#.3g", "sted": "#.2g"},
}

#: Printed under the temporal figures: which digits they show, and why.
FIGURE_DIGITS_NOTE = (
    "Digits: only those the input determines (docs/temporal.md): rounding ~20k-vertex frames to float32 moves the "
    "exact forms' KG, KSO and STED_t by up to 2.4e-7 and their STED and STED_s by 4e-4 (relative); rounding them to "
    "float32 or to 6 decimals moves the registered forms' KG, KSO and STED_t by up to 4e-4 and their STED and STED_s "
    "by 1.1e-3: 6 and 3 significant digits for the exact forms, 3 and 2 for the registered (whose registrations draw "
    "independently of how the frames are stored: 3 other orders moved them by 3e-12). Frames stored with 6 decimals "
    "can hold fewer of the exact forms' digits (STED_s on a mesh with very short edges: one digit); the JSON keeps "
    "every digit."
)


def format_figure(name: str, value: float, *, registered: bool) -> str:
    """One temporal figure as the tables print it: the digits of :data:`FIGURE_FORMATS` for its form.

    Args:
        name: one of :data:`~torchmeshmetric.temporal.figures.FIGURE_NAMES`.
        value: the figure.
        registered: whether it came from the registered form.

    Raises:
        KeyError: another ``name``.

    Example:
        >>> format_figure("kg", 0.0750344025, registered=True), format_figure("kg", 0.0750344025, registered=False)
        ('0.0750', '0.0750344')
    """
    return format_number(value, FIGURE_FORMATS[bool(registered)][name])


def temporal_report(figures: Mapping[str, TemporalFigures]) -> dict[str, dict[str, Any]]:
    """``{method: {figure: value, "registered": bool, ...}}`` (the reports' ``"temporal"`` entry).

    Args:
        figures: method name → its :class:`TemporalFigures`.

    Returns:
        method name → its figures as a dict (:meth:`TemporalFigures.as_dict`).

    Example:
        >>> f = TemporalFigures(1.0, 2.0, 0.1, 0.2, 0.1, True, 3, 100)
        >>> row = temporal_report({"qem": f}).get("qem", {})
        >>> row.get("kg"), row.get("registered")
        (1.0, True)
    """
    return {name: f.as_dict() for name, f in figures.items()}


def temporal_markdown(
    figures: Mapping[str, TemporalFigures], *, determinacy: Determinacy | None = None, sequence: str | None = None
) -> str:
    """A Markdown section with one row per method: KG, KSO, STED_s, STED_t, STED and the form used.

    Each figure prints the digits its form determines (:func:`format_figure`), and :data:`FIGURE_DIGITS_NOTE` follows
    the table.

    Args:
        figures: method name → its figures.
        determinacy: this run's measured determinacy with its ``"temporal"`` table
            (:func:`~torchmeshmetric.evaluation.determinacy.with_temporal_changes`, ``--determinacy``): each figure
            then keeps only the digits a second run on nudged frames left in place, at most those of
            :data:`FIGURE_FORMATS`. Without that table, the measured digits of :data:`FIGURE_FORMATS`.
        sequence: the sequence the figures are of, named in the section's title (a campaign prints one section per
            sequence).

    Returns:
        The Markdown section: a title, the table and the note on digits.

    Example:
        >>> f = TemporalFigures(1.0, 2.0, 0.1, 0.2, 0.1, True, 3, 100)
        >>> print(temporal_markdown({"qem": f}).splitlines()[4])
        | qem | 1.00 | 2.00 | 0.10 | 0.200 | 0.10 | registered |
    """
    measured = determinacy is not None and "temporal" in determinacy.changes
    lines = [
        "## Temporal metrics" + ("" if sequence is None else f" of sequence {sequence!r}") + " (KG, KSO, STED; "
        "docs/temporal.md)",
        "",
        "| method | " + " | ".join(FIGURE_LABELS[k] for k in FIGURE_NAMES) + " | form |",
        "|---|" + "---:|" * len(FIGURE_NAMES) + "---|",
    ]
    for i, (name, f) in enumerate(figures.items()):
        if measured:
            assert determinacy is not None
            specs = FIGURE_FORMATS[bool(f.registered)]
            texts = [determinacy.cell("temporal", i, k, float(getattr(f, k)), specs[k]) for k in FIGURE_NAMES]
        else:
            texts = [format_figure(k, float(getattr(f, k)), registered=f.registered) for k in FIGURE_NAMES]
        lines.append(f"| {markdown_cell(name)} | {' | '.join(texts)} | {'registered' if f.registered else 'exact'} |")
    if measured:
        assert determinacy is not None
        lines += ["", temporal_determinacy_note(determinacy)]
    else:
        lines += ["", FIGURE_DIGITS_NOTE]
    # The methods share the original's tracking, hence its registrations.
    unconverged = sorted({k for f in figures.values() for k in f.unconverged})
    if unconverged:
        lines += ["", unconverged_tracking_note(unconverged)]
    return "\n".join(lines) + "\n"


def temporal_determinacy_note(determinacy: Determinacy) -> str:
    """The note under the temporal figures of a run with a measured determinacy (instead of the measured digits)."""
    return (
        "Digits: only those this run's input determines: the figures were computed again on the frames with every "
        f"coordinate moved by up to one unit of its storage ({determinacy.rounding}, seed {determinacy.seed}) and "
        "stored in another order (the registered forms' registrations draw independently of it: this would catch one "
        "that does not), and each keeps the digits both runs share (at most 6 and 3 significant digits for the exact "
        "forms, 3 and 2 for the registered: docs/temporal.md); "
        "'~' marks a figure whose first digit moved. The JSON keeps every digit and, under 'determinacy' -> "
        "'changes' -> 'temporal', each figure's change."
    )


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
