"""Report writers: JSON, CSV and Markdown in the paper's layout, all written atomically.

Tables (paper, Section III): rows are algorithm x {(k-1)-th, k-th} mesh; columns the paper's Ave, Var, STD, MSE,
RMSE plus ours: Max (one-sided Hausdorff), P95 and PSNR (dB, peak = bounding-box diagonal of original frame k).

* Table I / II: the best pair (see :data:`~torchmeshmetric.evaluation.results.BEST_PAIR_RULE`), surface / vertex.
* Table III / IV: the average over all pairs (mean of the per-pair statistics), surface / vertex.
* Two-sided check (ours): the same averages for the reverse sets, reference → simplified.

Beyond the paper, the surface tables have a ``flicker`` row per algorithm (simplified frame ``k`` against the
simplified frame ``k-1`` moved onto frame ``k``), and every table ends with the registration's rows (method
independent): its ``residual`` to frame ``k`` and, when the true motion is known, its ``error``. They are the noise
floor of the ``(k-1)-th`` and ``flicker`` rows.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from torchmeshmetric._atomic import atomic_write
from torchmeshmetric._checks import check_flag
from torchmeshmetric._format import format_number, json_safe, markdown_cell
from torchmeshmetric._version import __version__
from torchmeshmetric.evaluation.comparison import comparison_markdown
from torchmeshmetric.evaluation.flicker import FLICKER
from torchmeshmetric.evaluation.results import BEST_PAIR_RULE, SET_NAMES, SequenceEvaluation

if TYPE_CHECKING:
    from torchmeshmetric.evaluation.determinacy import Determinacy

__all__ = [
    "COLUMNS",
    "COLUMN_FORMATS",
    "REGISTRATION_ROW",
    "markdown_report",
    "determinacy_note",
    "paper_tables",
    "report_dict",
    "stability_note",
    "statistic_cell",
    "statistic_cells",
    "table_rows",
    "write_csv",
    "write_json",
    "write_markdown",
]

#: (statistic key, column header) of every table.
COLUMNS: tuple[tuple[str, str], ...] = (
    ("ave", "Ave"),
    ("var", "Var"),
    ("std", "STD"),
    ("mse", "MSE"),
    ("rmse", "RMSE"),
    ("max", "Max"),
    ("p95", "P95"),
    ("psnr", "PSNR (dB)"),
)

#: Printed format of each column: only the digits the input determines. Measured (tests/evaluation/
#: report_determinacy.py, docs/statistics.md): rounding the paper's size of frame (the demo at resolution 160, ~20k
#: vertices) from float64 to float32, as frames are stored, moves Ave, Var, STD, MSE, RMSE, Median and P95 by up to
#: 2e-3 to 5e-3 relative (the simplifiers' discrete choices and the registration amplify the input's rounding), so
#: their third significant digit is not determined; Max moves by 5e-5 (three digits hold) and PSNR by 0.014 dB. The
#: full values stay in report.json / report.csv (data, for frames stored in float64).
#:
#: Every row prints these digits, those that go through the registration (the (k-1)-th and flicker rows, the
#: registration's own) too: the evaluation's registration computes in float64 (:data:`~torchmeshmetric.evaluation.
#: pipeline.REGISTRATION_DTYPE`: the same figures on every CPU) and draws its samples independently of how the
#: original frames are stored (``sampling="canonical"``, :data:`~torchmeshmetric.evaluation.pipeline.
#: REGISTRATION_SAMPLING`): the frames as stored against 3 orders of :func:`~torchmeshmetric.evaluation.determinacy.
#: relabel_frames` (the demo performer, 3 frames, QEM 50 %, float32 ``evaluate --temporal``) moved these rows' printed
#: columns by at most 7.0e-5 relative at resolution 160 (~20k vertices; the k-th rows 6.6e-5) and 1.9e-6 at
#: resolution 24, the Registration rows by 1e-11: the float32 level these formats were measured on. With the index
#: draws (``registration_options={"sampling": "index"}``) the storage order moved them by 3 % (Ave) to 55 % (Max)
#: (docs/statistics.md, "Storage order").
COLUMN_FORMATS: dict[str, str] = {
    "ave": "#.2g",
    "var": "#.2g",
    "std": "#.2g",
    "mse": "#.2g",
    "rmse": "#.2g",
    "max": "#.3g",
    "p95": "#.2g",
    "psnr": ".1f",
}

_MESH_LABELS = {"k_minus_1": "(k-1)-th", "k": "k-th"}
#: Algorithm cell of the registration's rows, and their mesh cells.
REGISTRATION_ROW = "Registration"
STABILITY_NOTE = (
    "the tables print only the digits that the input determines: rounding frames of ~20k vertices from float64 to "
    "float32 moves Ave, Var, STD, MSE, RMSE and P95 by up to 5e-3 (relative), Max by 5e-5 and PSNR by 0.014 dB "
    "(measured, docs/statistics.md), hence 2 significant digits, 3 for Max and one decimal for PSNR, in every row. "
    "The registration draws its samples independently of how the original frames are stored (3 other orders moved "
    "no printed figure: at most 7e-5 relative); frames stored with 6 decimals or with capture defects may hold "
    "fewer digits: --determinacy measures this run's digits (another rounding and another storage order). Compare "
    "methods to those digits; report.json keeps the full values."
)
"""What the measured determinacy of the figures (``tests/evaluation/report_determinacy.py``) says about their
digits; printed under the report's tables."""
_REGISTRATION_LABELS = {"residual": "residual to k", "error": "error to truth"}
_TITLES = {
    "I": "Table I: best pair, mesh surface distance",
    "II": "Table II: best pair, nearest vertex distance",
    "III": "Table III: average over pairs, mesh surface distance",
    "IV": "Table IV: average over pairs, nearest vertex distance",
    "III-reverse": "Two-sided check (ours): average over pairs, reference -> simplified, mesh surface distance",
    "IV-reverse": "Two-sided check (ours): average over pairs, reference -> simplified, nearest vertex distance",
}
_KIND = {
    "I": "surface",
    "II": "vertex",
    "III": "surface",
    "IV": "vertex",
    "III-reverse": "surface",
    "IV-reverse": "vertex",
}


def _best_index(methods: Mapping[str, SequenceEvaluation]) -> int:
    """One best pair for all methods (the rule depends only on the original frames).

    Raises:
        ValueError: no method (``write_csv(path, {})`` raised a bare ``StopIteration`` from here).
    """
    if not methods:
        raise ValueError("methods: expected at least one method, found none")
    first = next(iter(methods.values()))
    return first.best_pair_index()


def table_rows(
    methods: Mapping[str, SequenceEvaluation], table: str, *, best: int | None = None
) -> list[tuple[str, str, dict[str, float]]]:
    """Rows ``(algorithm, mesh, statistics)`` of one table.

    Per algorithm the ``(k-1)-th`` and ``k-th`` rows (and ``flicker`` in the surface tables when measured), then
    the registration's rows (algorithm :data:`REGISTRATION_ROW`): ``residual to k`` and, when the true motion is
    known, ``error to truth``.

    Args:
        methods: method name → its sequence evaluation (same original sequence).
        table: ``"I"``, ``"II"``, ``"III"``, ``"IV"``, ``"III-reverse"`` or ``"IV-reverse"``.
        best: the pair of Tables I/II (index into the pairs); default the best pair (:data:`BEST_PAIR_RULE`).
    """
    return [row[:3] for row in _rows(methods, table, best)]


def _rows(
    methods: Mapping[str, SequenceEvaluation], table: str, best: int | None = None
) -> list[tuple[str, str, dict[str, float], str]]:
    """:func:`table_rows` with the set key of each row (``registration:residual`` for a registration row)."""
    if table not in _TITLES:
        raise ValueError(f"table: expected one of {list(_TITLES)}, found {table!r}")
    kind = _KIND[table]
    rows: list[tuple[str, str, dict[str, float], str]] = []
    best = _best_index(methods) if best is None else best
    for name, seq in methods.items():
        if table in ("I", "II"):
            stats = {k: s.as_dict() for k, s in seq.pairs[best].statistics.items()}
        elif table.endswith("reverse"):
            stats = seq.aggregate_reverse()
            if not stats:
                continue
        else:
            stats = seq.aggregate()
        for mesh in ("k_minus_1", "k"):
            rows.append((name, _MESH_LABELS[mesh], stats[f"{kind}_{mesh}"], f"{kind}_{mesh}"))
        if kind == "surface" and FLICKER in stats:
            rows.append((name, FLICKER, stats[FLICKER], FLICKER))
    if rows:
        first = next(iter(methods.values()))
        if table in ("I", "II"):
            pair = first.pairs[best]
            registration: dict[str, dict[str, float]] = {"residual": pair.registration_statistics.as_dict()}
            if pair.registration_error_statistics is not None:
                registration["error"] = pair.registration_error_statistics.as_dict()
        else:
            registration = first.aggregate_registration()
        for what, reg_stats in registration.items():
            rows.append((REGISTRATION_ROW, _REGISTRATION_LABELS[what], reg_stats, f"registration:{what}"))
    return rows


def statistic_cell(value: float, statistic: str) -> str:
    """One statistic as the tables print it: the digits of :data:`COLUMN_FORMATS`, the same in every row.

    The one place that formats a cell; the tables, the campaign, the sweep, the plots' labels and the ``register``
    command print through it. The rows that go through the registration print the digits of the others (see
    :data:`COLUMN_FORMATS`).

    Args:
        value: the statistic.
        statistic: its column key (:data:`COLUMNS`: ``"ave"``, ``"var"``, ..., ``"psnr"``).

    Raises:
        KeyError: another ``statistic``.

    Example:
        >>> statistic_cell(0.0158, "rmse"), statistic_cell(0.08594, "max"), statistic_cell(42.41, "psnr")
        ('0.016', '0.0859', '42.4')
    """
    return format_number(value, COLUMN_FORMATS[statistic])


def statistic_cells(stats: Mapping[str, float]) -> list[str]:
    """The table cells of one row of statistics, in :data:`COLUMNS` order (:func:`statistic_cell`).

    Args:
        stats: the row's statistics.

    Example:
        >>> stats = {"ave": 0.0123456, "var": 1e-4, "std": 0.01, "mse": 2.5e-4, "rmse": 0.0158,
        ...          "max": 0.08594, "p95": 0.0315, "psnr": 42.41}
        >>> statistic_cells(stats)
        ['0.012', '0.00010', '0.010', '0.00025', '0.016', '0.0859', '0.032', '42.4']
    """
    return [statistic_cell(stats[k], k) for k, _ in COLUMNS]


def paper_tables(
    methods: Mapping[str, SequenceEvaluation],
    *,
    reverse: bool = True,
    determinacy: Determinacy | None = None,
    json_file: str = "report.json",
) -> str:
    """The paper's Tables I-IV (plus the two-sided check) as Markdown, the digits of :data:`COLUMN_FORMATS`.

    Args:
        methods: method name → sequence evaluation; all on the same original sequence.
        reverse: add the two reverse tables when the evaluations are two-sided.
        determinacy: this run's measured determinacy (:func:`~torchmeshmetric.evaluation.determinacy.
            measure_determinacy`): each cell then prints only the digits a second run on nudged frames left in
            place, at most those of :data:`COLUMN_FORMATS`.
        json_file: what the note under the tables names as keeping the full values: the JSON report's file name,
            or e.g. ``"the JSON report (--out)"`` for tables printed without one.

    Returns:
        The Markdown text: one ``###`` section per table (a header row, then per method its ``(k-1)-th``, ``k-th``
        and, in the surface tables, ``flicker`` rows, then the registration's rows), the best pair rule and the
        notes on the registration rows and the digits; ends with a newline.

    Raises:
        ValueError: ``methods`` is empty.
        TypeError: ``reverse`` is not a bool.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 2
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]  # every vertex 0.01 away
        >>> seq = evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)
        >>> lines = paper_tables({"moved": seq}).splitlines()
        >>> lines[0]
        '### Table I: best pair, mesh surface distance (frames 0 -> 1)'
        >>> table_2 = lines[lines.index("### Table II: best pair, nearest vertex distance (frames 0 -> 1)") :]
        >>> k_th = next(line for line in table_2 if line.startswith("| moved | k-th"))
        >>> k_th.split(" | ")[2]  # Ave: 0.01 exactly
        '0.010'
    """
    reverse = check_flag(reverse, "reverse")
    best = _best_index(methods)  # refuses no method
    frame = next(iter(methods.values())).pairs[best].frame
    header = "| Algorithm | Mesh | " + " | ".join(h for _, h in COLUMNS) + " |"
    rule = "|" + "---|" * (len(COLUMNS) + 2)
    out = []
    tables = ["I", "II", "III", "IV"] + (["III-reverse", "IV-reverse"] if reverse else [])
    for table in tables:
        rows = _rows(methods, table)
        if not rows:
            continue
        title = _TITLES[table] + (f" (frames {frame - 1} -> {frame})" if table in ("I", "II") else "")
        out += [f"### {title}", "", header, rule]
        for i, (name, mesh, stats, _) in enumerate(rows):
            if determinacy is None:
                cells = statistic_cells(stats)
            else:
                cells = [determinacy.cell(table, i, k, stats[k], COLUMN_FORMATS[k]) for k, _ in COLUMNS]
            out.append(f"| {markdown_cell(name)} | {mesh} | " + " | ".join(cells) + " |")
        out.append("")
    out.append(f"Best pair rule: {BEST_PAIR_RULE}. Averages: mean over pairs of each per-pair statistic.")
    out.append("")
    out.append(
        "flicker: simplified frame k against the simplified frame k-1 moved onto frame k by the registration. "
        f"{REGISTRATION_ROW} rows (the same for every algorithm): the registration of original k-1 onto k, its "
        "residual (registered vertices to the surface of frame k) and, when the true motion is known, its error; "
        "differences between algorithms on the (k-1)-th and flicker rows smaller than these are not meaningful. "
        f"Stability: {stability_note(determinacy, json_file=json_file)}"
    )
    unconverged = [f"{k - 1} -> {k}" for k in unconverged_frames(methods)]
    if unconverged:
        out += ["", unconverged_note(unconverged)]
    return "\n".join(out) + "\n"


def unconverged_frames(methods: Mapping[str, SequenceEvaluation]) -> list[int]:
    """Frames ``k`` whose registration of original ``k-1`` onto ``k`` says ``converged=False``, in any method.

    The methods share the registrations of the original pairs, so one list serves every method's rows.
    """
    return sorted({p.frame for seq in methods.values() for p in seq.pairs if not p.registration_converged})


def unconverged_note(pairs: Sequence[str]) -> str:
    """The line under the tables that names the frame pairs (``"1 -> 2"``, ...) whose registration is not trusted.

    The registration's own warning (``RegistrationWarning``) says why when it is computed, but not when the
    registration comes from a cache, and it scrolls away in a long run: tables built on such a pair must say so
    where their figures are read (:func:`paper_tables`, the campaign's tables).
    """
    several = len(pairs) > 1
    return (
        f"Registration not converged for frame pair{'s' if several else ''} {', '.join(pairs)} (the JSON report: "
        "each pair's 'registration' -> 'converged'; the RegistrationWarning printed when it was computed says why): "
        f"the (k-1)-th and flicker figures of {'those pairs' if several else 'that pair'}, and the averages over "
        "pairs, rest on a registration that did not meet its convergence or plausibility checks (docs/registration.md)."
    )


def stability_note(determinacy: Determinacy | None = None, *, json_file: str = "report.json") -> str:
    """What the tables' digits mean: :data:`STABILITY_NOTE`, or :func:`determinacy_note` of a measured run.

    Args:
        determinacy: the run's measured determinacy, if any.
        json_file: what keeps the full values: the report's file (``campaign.json`` for a campaign's tables), or
            e.g. ``"the JSON report (--out)"`` for tables printed without one.
    """
    note = STABILITY_NOTE if determinacy is None else determinacy_note(determinacy)
    return note.replace("report.json", json_file)


def determinacy_note(determinacy: Determinacy) -> str:
    """The note under the tables of a run with a measured determinacy (instead of :data:`STABILITY_NOTE`)."""
    return (
        "the tables print only the digits this run's input determines: the evaluation was repeated on the frames with "
        f"every coordinate moved by up to one unit of its storage ({determinacy.rounding}, seed {determinacy.seed}) "
        "and stored in another order (vertices renumbered, faces reordered, corners rotated: the registration draws "
        "independently of it, so this would catch a registration that does not), and each cell prints what both runs "
        "print alike (at most 2 significant digits, 3 for Max, one decimal for PSNR); '~' marks a figure none of "
        "whose digits held, printed as the midpoint "
        "of both runs (PSNR: not even the units). report.json keeps the full values and, under 'determinacy', each "
        "cell's change and the second run's value."
    )


def report_dict(
    methods: Mapping[str, SequenceEvaluation],
    *,
    settings: Mapping[str, Any] | None = None,
    comparisons: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """JSON-ready report: ``{"tool", "version", "settings", "set_names", "methods": {name: sequence}}``.

    Each method holds ``pairs`` (per frame pair: the four sets ``surface_k``, ``surface_k_minus_1``, ``vertex_k``,
    ``vertex_k_minus_1`` with ``ave``, ``var``, ``std``, ``mse``, ``rmse`` and the further statistics, ``reverse``,
    ``registration``, ``timings``), ``aggregate`` under the same keys and ``best_pair``. Non-finite floats are
    written as the strings ``"nan"``, ``"inf"``. With ``comparisons`` (from
    :func:`~torchmeshmetric.evaluation.compare_methods`) the report also holds ``"comparisons"``.

    Args:
        methods: method name → its sequence evaluation (all on the same original sequence).
        settings: the run's settings, written under ``"settings"`` (default: ``{}``).
        comparisons: the verdicts of :func:`~torchmeshmetric.evaluation.compare_methods`, written under
            ``"comparisons"`` when given.

    Returns:
        A dict of plain Python values (str, int, float, list, dict) that :func:`json.dumps` writes with
        ``allow_nan=False``; the values are full precision (not the tables' digits).

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 2
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]  # every vertex 0.01 away
        >>> report = report_dict({"moved": evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)})
        >>> pairs = report["methods"].get("moved").get("pairs")
        >>> first = pairs[0]
        >>> sorted(report), first["frame"]
        (['methods', 'set_names', 'settings', 'tool', 'version'], 1)
        >>> vertex_k = first["vertex_k"]
        >>> round(vertex_k["max"], 12), vertex_k["count"]
        (0.01, 42)
    """
    return json_safe(
        {
            "tool": "torchmeshmetric",
            "version": __version__,
            "settings": dict(settings or {}),
            "set_names": list(SET_NAMES),
            "methods": {name: seq.as_dict() for name, seq in methods.items()},
            **({"comparisons": dict(comparisons)} if comparisons is not None else {}),
        }
    )


def write_json(path: str | os.PathLike[str], report: Mapping[str, Any], *, overwrite: bool = False) -> Path:
    """Write a :func:`report_dict` as strict JSON, atomically.

    Args:
        path: destination file (``.json``).
        report: the report, e.g. from :func:`report_dict` (only strict JSON values: non-finite floats as strings).
        overwrite: replace an existing file; by default an existing ``path`` is left untouched.

    Returns:
        The path written.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        ValueError: ``report`` holds a non-finite float (strict JSON has none; :func:`report_dict` writes them as
            strings).
        TypeError: ``overwrite`` is not a bool, or ``report`` holds a value JSON cannot write.

    Example:
        >>> import json, os, tempfile
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     path = write_json(os.path.join(folder, "report.json"), {"tool": "torchmeshmetric", "psnr": "inf"})
        ...     json.loads(path.read_text())
        {'tool': 'torchmeshmetric', 'psnr': 'inf'}
    """
    overwrite = check_flag(overwrite, "overwrite")
    return atomic_write(path, json.dumps(report, indent=2, allow_nan=False) + "\n", overwrite=overwrite)


def write_markdown(
    path: str | os.PathLike[str],
    methods: Mapping[str, SequenceEvaluation],
    *,
    overwrite: bool = False,
    extra: str = "",
    comparisons: Mapping[str, Any] | None = None,
    determinacy: Determinacy | None = None,
    json_file: str = "report.json",
) -> Path:
    """Write :func:`markdown_report` to a file, atomically.

    Args:
        path: destination file (``.md``).
        methods: method name → its sequence evaluation (all on the same original sequence).
        overwrite: replace an existing file; by default an existing ``path`` is left untouched.
        extra: Markdown appended after the tables (e.g. the MPEG section of ``--mpeg``).
        comparisons: the verdicts of :func:`~torchmeshmetric.evaluation.compare_methods`, printed as
            :func:`~torchmeshmetric.evaluation.comparison.comparison_markdown` tables.
        determinacy: this run's measured determinacy, as in :func:`paper_tables`.
        json_file: the JSON report the notes name as keeping the full values, as in :func:`paper_tables`.

    Returns:
        The path written.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        ValueError: ``methods`` is empty.
        TypeError: ``overwrite`` is not a bool.

    Example:
        >>> import os, tempfile, trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 2
        >>> seq = evaluate_sequence(frames, frames, registration_fn=lambda s, t: s)
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     text = write_markdown(os.path.join(folder, "report.md"), {"same": seq}).read_text()
        >>> text.splitlines()[0], "| same | k-th | 0.0 |" in text
        ('# torchmeshmetric evaluation', True)
    """
    overwrite = check_flag(overwrite, "overwrite")
    text = markdown_report(methods, extra=extra, comparisons=comparisons, determinacy=determinacy, json_file=json_file)
    return atomic_write(path, text, overwrite=overwrite)


def markdown_report(
    methods: Mapping[str, SequenceEvaluation],
    *,
    extra: str = "",
    comparisons: Mapping[str, Any] | None = None,
    determinacy: Determinacy | None = None,
    json_file: str = "report.json",
) -> str:
    """The text of ``report.md``: :func:`paper_tables`, ``comparisons``' verdict tables and ``extra`` Markdown.

    ``extra`` is e.g. the MPEG section of ``--mpeg``; ``determinacy`` and ``json_file`` as in :func:`paper_tables`.
    """
    text = "# torchmeshmetric evaluation\n\n" + paper_tables(methods, determinacy=determinacy, json_file=json_file)
    if comparisons:
        text += "\n## Comparisons with confidence\n\n" + comparison_markdown(comparisons)
    if extra:
        text += "\n" + extra
    return text


def write_csv(
    path: str | os.PathLike[str], methods: Mapping[str, SequenceEvaluation], *, overwrite: bool = False
) -> Path:
    """Write every table and every pair as CSV rows, atomically.

    Columns: ``table`` (``I``..``IV``, ``III-reverse``, ``IV-reverse``, or ``pair`` for per-frame rows), ``algorithm``,
    ``set`` (e.g. ``surface_k_minus_1``, ``flicker``; ``reverse:...`` for reverse sets; ``registration:residual``
    and ``registration:error`` for the registration's rows), ``frame`` (pair rows and tables I/II), then the
    statistics ``ave, var, std, mse, rmse, max, p95, psnr`` at full precision (``repr`` of the float).

    Args:
        path: destination file (``.csv``).
        methods: method name → its sequence evaluation (all on the same original sequence).
        overwrite: replace an existing file; by default an existing ``path`` is left untouched.

    Returns:
        The path written.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        TypeError: ``overwrite`` is not a bool.
        ValueError: ``methods`` is empty.

    Example:
        >>> import csv, os, tempfile, trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 2
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]  # every vertex 0.01 away
        >>> seq = evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     rows = list(csv.DictReader(write_csv(os.path.join(folder, "r.csv"), {"moved": seq}).open()))
        >>> row = next(r for r in rows if r["table"] == "pair" and r["set"] == "vertex_k")
        >>> row["frame"], round(float(row["max"]), 12)
        ('1', 0.01)
    """
    overwrite = check_flag(overwrite, "overwrite")
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    keys = [k for k, _ in COLUMNS]
    writer.writerow(["table", "algorithm", "set", "frame", *keys])
    best = _best_index(methods)
    for table in ("I", "II", "III", "IV", "III-reverse", "IV-reverse"):
        for name, _, stats, set_name in _rows(methods, table):
            if table.endswith("reverse") and name != REGISTRATION_ROW:
                set_name = f"reverse:{set_name}"
            frame = next(iter(methods.values())).pairs[best].frame if table in ("I", "II") else ""
            writer.writerow([table, name, set_name, frame, *(repr(float(stats[k])) for k in keys)])
    for name, seq in methods.items():
        for pair in seq.pairs:
            sets = [(s, pair.statistics[s]) for s in pair.set_names]
            sets += [(f"reverse:{s}", st) for s, st in pair.reverse_statistics.items()]
            for set_name, st in sets:
                d = st.as_dict()
                writer.writerow(["pair", name, set_name, pair.frame, *(repr(float(d[k])) for k in keys)])
    return atomic_write(path, buf.getvalue(), overwrite=overwrite)
