"""Which digits of a report the input determines, measured per run: a second evaluation on nudged frames.

A frame stored in float32, or in a text file with 6 decimals, is its true self rounded; the report's figures are
computed through discrete choices (the registration's, a simplifier's) that can turn that rounding into a change
far larger than itself (docs/statistics.md, "Which digits the input determines"). The tables' fixed digits
(:data:`~torchmeshmetric.evaluation.reports.COLUMN_FORMATS`) come from a measurement on the library's own frames;
this module measures the run at hand instead: every input frame (originals and simplified) is moved by up to one unit
of its storage, the evaluation is repeated, and each table cell prints only the digits both runs share.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from torchmeshmetric._format import format_number
from torchmeshmetric.evaluation.results import SequenceEvaluation
from torchmeshmetric.structures import Mesh

__all__ = [
    "Determinacy",
    "determined_cell",
    "determined_digits",
    "measure_determinacy",
    "nudge_frames",
    "raised_fraction",
    "row_changes",
    "storage_unit",
    "value_change",
    "with_temporal_changes",
]

#: The tables compared (those of :func:`~torchmeshmetric.evaluation.reports.paper_tables`).
_TABLES = ("I", "II", "III", "IV", "III-reverse", "IV-reverse")


def storage_unit(rounding: str | int) -> str:
    """The canonical name of a storage rounding: ``"float32"`` or ``"<d> decimals"`` (``"1 decimal"``).

    Args:
        rounding: ``"float32"`` (frames stored as float32: one unit is the float32 spacing at each coordinate) or
            the number of decimals ``d`` of a text file (one unit is ``10**-d``), as an int or a digit string.

    Raises:
        ValueError: anything else, naming ``rounding``.

    Example:
        >>> storage_unit("float32"), storage_unit(6), storage_unit("1")
        ('float32', '6 decimals', '1 decimal')
    """
    if rounding == "float32":
        return "float32"
    if isinstance(rounding, str) and rounding.isascii() and rounding.isdigit():  # not "٣" nor "²"
        rounding = int(rounding)
    if isinstance(rounding, int) and not isinstance(rounding, bool) and 0 <= rounding <= 15:
        return f"{rounding} decimal{'' if rounding == 1 else 's'}"
    raise ValueError(f"rounding: expected 'float32' or a number of decimals 0..15, found {rounding!r}")


def nudge_frames(frames: Sequence[Mesh], rounding: str | int, *, seed: int = 0) -> list[Mesh]:
    """The frames with every vertex coordinate moved by up to one unit of its storage, as a function of its value.

    Each coordinate ``x`` (of axis ``a``) moves by ``u * unit(x)`` with ``u`` in ``[-1, 1)`` drawn from a hash of
    ``(x, a, seed)`` (splitmix64 of the float64 bits: the same on every machine, whatever the vertex order). Like
    the storage's own rounding, the nudge is a function of the stored value: equal coordinates move alike, so
    coincident vertices (a captured frame's duplicates, a simplified vertex kept at an original's position) stay
    coincident, where independent draws would pull them apart and measure a change the storage cannot make. The
    move is computed in float64 and the result rounded to each frame's dtype, so float32 frames nudged by float32
    units land on the coordinate or one of its two neighbours, and float64 frames move continuously. Zero
    coordinates stay zero under ``"float32"`` (their storage is exact). A unit finer than the frame's own dtype at a
    coordinate (``9`` decimals of a float32 frame of coordinates ~100) is raised to that dtype's spacing there: the
    run holds the frame at its dtype, itself a rounding of the file, and a finer step would round away
    (:func:`raised_fraction` says how many). Faces are shared, not copied.

    Args:
        frames: the meshes, any length (nudge the originals and the simplified frames with the same ``seed``).
        rounding: see :func:`storage_unit`.
        seed: mixed into the hash: another seed, another nudge.

    Returns:
        One new :class:`Mesh` per frame: ``(V, 3)`` vertices of the frame's dtype and device, the same faces.

    Example:
        >>> mesh = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> moved = nudge_frames([mesh], 3)[0].verts
        >>> bool(((moved - mesh.verts).abs() <= 1e-3).all())
        True
    """
    out = []
    for frame in frames:
        v = frame.verts.detach().to("cpu", torch.float64)
        unit = _units(v, rounding, frame.verts.dtype)[0]
        step = torch.from_numpy(_hashed_uniform(v.numpy(), seed)) * unit
        moved = (v + step).to(device=frame.verts.device, dtype=frame.verts.dtype)
        out.append(Mesh(moved, frame.faces, validate=False))
    return out


def raised_fraction(frames: Sequence[Mesh], rounding: str | int) -> float:
    """The share of the frames' coordinates whose storage unit is finer than their own dtype holds.

    :func:`nudge_frames` moves those by one unit of the frame's dtype instead (``--determinacy 9`` on float32
    frames in millimetres: nearly all of them); a caller says so, as the measured digits are then the dtype's.

    Example:
        >>> mesh = Mesh(torch.tensor([[100.0, 0, 0], [0, 100, 0], [0, 0, 100]]), torch.tensor([[0, 1, 2]]))
        >>> raised_fraction([mesh], 9), raised_fraction([mesh], 3)
        (0.3333333333333333, 0.0)
    """
    raised = total = 0
    for frame in frames:
        _, finer = _units(frame.verts.detach().to("cpu", torch.float64), rounding, frame.verts.dtype)
        raised, total = raised + int(finer.sum()), total + finer.numel()
    return raised / total if total else 0.0


def _spacing(v: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    """The spacing of ``dtype``'s numbers at each of ``v`` (float64, rounded to ``dtype`` first); 0 at zero."""
    significand = round(1 - math.log2(torch.finfo(dtype).eps))  # 24 bits for float32, 53 for float64
    _, exponent = torch.frexp(v.to(dtype).to(torch.float64))
    unit = torch.ldexp(torch.ones_like(v), exponent - significand)
    return torch.where(v == 0, torch.zeros_like(v), unit)


def _units(v: torch.Tensor, rounding: str | int, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor]:
    """One storage unit at each coordinate of ``v`` (float64), at least ``dtype``'s spacing; and where it was less.

    A frame held at ``dtype`` cannot move by less than its spacing: a finer step rounds away (often entirely), and
    the run would measure nothing. The dtype is itself a rounding of the stored file, so its unit is the one the run
    is sensitive to there.
    """
    unit_name = storage_unit(rounding)
    if unit_name == "float32":
        unit = _spacing(v, torch.float32)
    else:
        unit = torch.full_like(v, 10.0 ** -int(unit_name.split()[0]))
    own = _spacing(v, dtype)
    return torch.maximum(unit, own), unit < own


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _hashed_uniform(values: np.ndarray, seed: int) -> np.ndarray:
    """``(V, 3)`` uniform numbers in ``[-1, 1)``, each a function of its value's float64 bits, its axis and ``seed``.

    splitmix64 (Steele, Lea and Flood, 2014) in numpy's wrapping uint64 arithmetic; ``-0.0`` counts as ``0.0``.
    """
    bits = np.ascontiguousarray(values + 0.0, dtype=np.float64).view(np.uint64)
    axis = np.arange(values.shape[-1], dtype=np.uint64) * np.uint64(0xD1B54A32D192ED03)
    salt = np.full(1, seed & 0xFFFFFFFFFFFFFFFF, dtype=np.uint64) * _GOLDEN  # an array: wraps without a warning
    z = (bits ^ axis ^ salt) + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0**-52 - 1.0


def determined_digits(change: float, spec: str) -> int:
    """The digits of format ``spec`` that a change leaves: significant (``"#.2g"``) or decimals (``".1f"``).

    ``floor(-log10(change))``, at most the format's own; below 1 (below 0 for decimals) when even the first moved.

    Example:
        >>> determined_digits(2e-3, "#.2g"), determined_digits(0.0, "#.3g"), determined_digits(2.0, ".1f")
        (2, 3, -1)
    """
    most = int(spec.rstrip("fg").split(".")[-1])
    return most if change == 0 else min(most, math.floor(-math.log10(change)) if math.isfinite(change) else -1)


def determined_cell(value: Any, change: float, spec: str) -> str:
    """``value`` printed with the digits of ``spec`` that ``change`` leaves (:func:`determined_digits`).

    A significant-digit ``spec`` (``"#.2g"``) takes the relative change, a fixed-point one (``".1f"``) the absolute
    one; at least one significant digit (no decimal) is printed, prefixed with ``~`` when even it moved.

    Example:
        >>> determined_cell(0.0123456, 0.013, "#.2g"), determined_cell(0.0123456, 0.2, "#.2g")
        ('0.01', '~0.01')
        >>> determined_cell(-0.10612, 0.0, "#.3g"), determined_cell(61.27, 0.3, ".1f")
        ('-0.106', '61')
    """
    digits = determined_digits(change, spec)
    if spec.endswith("g"):
        # '#' keeps a significant trailing zero (0.010); with one digit it leaves a bare point ("2.e-07", "3.").
        text = format_number(value, f"#.{max(digits, 1)}g").replace(".e", "e").rstrip(".")
        return text if digits >= 1 else f"~{text}"
    text = format_number(value, f".{max(digits, 0)}f")
    return text if digits >= 0 else f"~{text}"


def value_change(a: float, b: float, *, relative: bool = True) -> float:
    """How far ``b`` is from ``a``: relative to the larger magnitude, or absolute; 0 for equal values (two NaNs too).

    The change :attr:`Determinacy.changes` holds (relative for every statistic but ``psnr``), and that of a figure
    printed outside the tables.

    Example:
        >>> value_change(2.0, 2.5), value_change(float("nan"), float("nan")), value_change(1.0, float("inf"))
        (0.2, 0.0, inf)
        >>> value_change(-12.5, -12.0, relative=False)
        0.5
    """
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    if not (math.isfinite(a) and math.isfinite(b)):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b)) if relative else abs(a - b)


@dataclass(frozen=True)
class Determinacy:
    """The change of every table cell between a run and a second run on nudged frames.

    Attributes:
        rounding: the storage unit the frames were nudged by (:func:`storage_unit`).
        seed: the nudge's seed.
        changes: per table (``"I"`` .. ``"IV-reverse"``), per row in the table's order, per statistic: the change,
            relative to the larger magnitude for every statistic but ``psnr`` (absolute, dB).
    """

    rounding: str
    seed: int
    changes: Mapping[str, list[dict[str, float]]]

    def cell(self, table: str, row: int, key: str, value: Any, spec: str) -> str:
        """The cell of ``value`` with only the digits the nudge left in place (at most those of ``spec``).

        A significant-digit ``spec`` (``"#.2g"``) keeps ``floor(-log10(relative change))`` digits, at least one; a
        fixed-point one (``".1f"``) keeps ``floor(-log10(absolute change))`` decimals, at least none. A cell
        whose first printed digit moved is prefixed with ``~``.

        Example:
            >>> d = Determinacy("float32", 0, {"III": [{"ave": 0.013, "psnr": 0.3}]})
            >>> d.cell("III", 0, "ave", 0.0123456, "#.2g"), d.cell("III", 0, "psnr", 61.27, ".1f")
            ('0.01', '61')
            >>> Determinacy("float32", 0, {"III": [{"ave": 0.2}]}).cell("III", 0, "ave", 0.0123456, "#.2g")
            '~0.01'
            >>> Determinacy("float32", 0, {"III": [{"var": 0.05}]}).cell("III", 0, "var", 2.2e-7, "#.2g")
            '2e-07'
        """
        return determined_cell(value, self.changes[table][row][key], spec)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: ``{"rounding", "seed", "changes": {table: [row: {statistic: change}]}}``."""
        return {"rounding": self.rounding, "seed": self.seed, "changes": {t: list(r) for t, r in self.changes.items()}}


def measure_determinacy(
    methods: Mapping[str, SequenceEvaluation],
    nudged: Mapping[str, SequenceEvaluation],
    rounding: str | int,
    *,
    seed: int = 0,
) -> Determinacy:
    """Compare a run's tables with those of the same evaluation on :func:`nudge_frames`' frames.

    Args:
        methods: the run's evaluations (method name → sequence evaluation).
        nudged: the same methods evaluated on the nudged original and simplified frames (same settings).
        rounding: the nudge's storage unit (:func:`storage_unit`).
        seed: the nudge's seed.

    Returns:
        :class:`Determinacy` over every table of :func:`~torchmeshmetric.evaluation.reports.paper_tables`; the
        best pair (Tables I/II) is the run's, in both.

    Raises:
        ValueError: the two runs hold other methods or other frame pairs.

    Example:
        >>> from torchmeshmetric.cli._shared import evaluate_methods  # doctest: +SKIP
        >>> d = measure_determinacy(results, nudged_results, "float32")  # doctest: +SKIP
        >>> paper_tables(results, determinacy=d)  # doctest: +SKIP
    """
    from torchmeshmetric.evaluation.reports import table_rows

    if list(methods) != list(nudged) or any(
        [p.frame for p in methods[m].pairs] != [p.frame for p in nudged[m].pairs] for m in methods
    ):
        raise ValueError("nudged: expected the same methods and frame pairs as methods")
    best = next(iter(methods.values())).best_pair_index() if methods else 0
    changes: dict[str, list[dict[str, float]]] = {}
    for table in _TABLES:
        rows, again = table_rows(methods, table, best=best), table_rows(nudged, table, best=best)
        changes[table] = row_changes([r[2] for r in rows], [r[2] for r in again])
    return Determinacy(storage_unit(rounding), seed, changes)


def row_changes(rows: Sequence[Mapping[str, Any]], again: Sequence[Mapping[str, Any]]) -> list[dict[str, float]]:
    """The change of each statistic of a table's rows between two runs, as :attr:`Determinacy.changes` holds it.

    Relative to the larger magnitude for every statistic but ``psnr`` (absolute, dB); 0 where both are equal (two
    NaNs included), infinite where only one is finite.

    Args:
        rows: the run's rows, each ``{statistic: value}`` holding every statistic of the tables' columns.
        again: the same rows of the second run, in the same order.

    Raises:
        ValueError: the two runs hold a different number of rows.

    Example:
        >>> stats = {"ave": 2.0, "var": 1.0, "std": 1.0, "mse": 5.0, "rmse": 2.2, "max": 4.0, "p95": 3.0, "psnr": 40.0}
        >>> change = row_changes([stats], [{**stats, "ave": 2.5, "psnr": 40.25}]).pop()
        >>> change.get("ave"), change.get("psnr"), change.get("max")
        (0.2, 0.25, 0.0)
    """
    from torchmeshmetric.evaluation.reports import COLUMNS

    if len(rows) != len(again):
        raise ValueError(f"again: expected {len(rows)} rows as in rows, found {len(again)}")
    return [
        {key: value_change(float(a[key]), float(b[key]), relative=key != "psnr") for key, _ in COLUMNS}
        for a, b in zip(rows, again, strict=True)
    ]


def with_temporal_changes(
    determinacy: Determinacy,
    figures: Mapping[str, Mapping[str, Any]],
    nudged: Mapping[str, Mapping[str, Any]],
    names: Sequence[str],
) -> Determinacy:
    """``determinacy`` with a ``"temporal"`` table: the relative change of each temporal figure per method.

    The temporal section's counterpart of :func:`measure_determinacy` (``--temporal`` with ``--determinacy``): the
    run's figures against those of the same frames nudged as the tables' were.

    Args:
        determinacy: the tables' measurement.
        figures: method name → the run's figures (a dict holding each of ``names``; the methods in table order).
        nudged: the same methods' figures on the nudged frames.
        names: the figures compared (``FIGURE_NAMES``).

    Raises:
        ValueError: ``nudged`` holds other methods.

    Example:
        >>> d = with_temporal_changes(Determinacy("float32", 0, {}), {"a": {"kg": 2.0}}, {"a": {"kg": 2.5}}, ["kg"])
        >>> d.changes["temporal"]  # relative to the larger magnitude, as the tables' changes
        [{'kg': 0.2}]
    """
    if list(figures) != list(nudged):
        raise ValueError(f"nudged: expected the methods {list(figures)}, found {list(nudged)}")
    rows = [{k: value_change(float(figures[m][k]), float(nudged[m][k])) for k in names} for m in figures]
    return Determinacy(determinacy.rounding, determinacy.seed, {**determinacy.changes, "temporal": rows})
