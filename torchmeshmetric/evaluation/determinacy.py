"""Which digits of a report the input determines, measured per run: a second evaluation on nudged frames.

A frame stored in float32, or in a text file with 6 decimals, is its true self rounded; the report's figures are
computed through discrete choices (the registration's, a simplifier's) that can turn that rounding into a change
far larger than itself (docs/statistics.md, "Which digits the input determines"). The tables' fixed digits
(:data:`~torchmeshmetric.evaluation.reports.COLUMN_FORMATS`) come from a measurement on the library's own frames;
this module measures the run at hand instead: every input frame (originals and simplified) is moved by up to one unit
of its storage and stored in another order (:func:`relabel_frames`: the evaluation's registration draws
independently of it, so a registration that did not would show here), the evaluation is repeated, and each table
cell prints only the digits both runs print alike (:func:`shared_cell`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
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
    "relabel_frames",
    "row_changes",
    "row_values",
    "shared_cell",
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
    z = _splitmix(bits ^ axis ^ salt)
    return (z >> np.uint64(11)).astype(np.float64) * 2.0**-52 - 1.0


def _splitmix(z: np.ndarray) -> np.ndarray:
    """splitmix64's output function of each uint64 of ``z`` (wrapping arithmetic)."""
    z = z + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def _hashed_order(count: int, salt: np.ndarray) -> np.ndarray:
    """A permutation of ``range(count)``: the indices sorted by their splitmix64 hash with ``salt``."""
    return np.argsort(_splitmix(np.arange(count, dtype=np.uint64) ^ salt), kind="stable")


def relabel_frames(frames: Sequence[Mesh], *, seed: int = 0) -> list[Mesh]:
    """The frames stored in another order: vertices renumbered, faces reordered, each face's corners rotated.

    The same surfaces, as another tool (a re-export, an OBJ to PLY conversion) may store them. The evaluation's
    registration draws its samples independently of the storage order (``sampling="canonical"``); with the index
    draws (``{"sampling": "index"}``, :func:`~torchmeshmetric.registration.register_nonrigid`'s default) the storage
    order acts as their random seed and moves every figure that goes through them (docs/registration.md,
    "Stability"). ``--determinacy``'s second run stores its frames this way, so the change it measures would include
    a registration that follows the storage order. The orders are drawn from a hash of ``(seed, V, F, index)``
    (splitmix64: the same on every machine), so frames with the same vertex and face counts get the same
    relabelling, and sequences that share a connectivity (a frame and its distorted copy; the frames of a tracked
    sequence) still
    share it. Each face keeps its orientation (its corners are rotated, never swapped). Vertices are moved, not
    copied into another dtype: the coordinates are the frame's own bits.

    Args:
        frames: the meshes, any length.
        seed: mixed into the hash: another seed, another order.

    Returns:
        One new :class:`Mesh` per frame, on the frame's device.

    Example:
        >>> mesh = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]),
        ...             torch.tensor([[0, 1, 2], [0, 2, 3], [0, 3, 1]]))
        >>> other = relabel_frames([mesh])[0]
        >>> normals = lambda m: sorted(map(tuple, m.face_normals().tolist()))  # the same oriented faces
        >>> normals(other) == normals(mesh), other.faces.tolist() != mesh.faces.tolist()
        (True, True)
    """
    out = []
    for frame in frames:
        count, num_faces = frame.num_verts, frame.num_faces
        base = _splitmix(np.array([seed & 0xFFFFFFFFFFFFFFFF, count, num_faces], dtype=np.uint64)).sum(dtype=np.uint64)
        salts = _splitmix(base + np.arange(3, dtype=np.uint64))
        order = _hashed_order(count, salts[0])  # the new vertex i is the old vertex order[i]
        new_index = np.empty(count, dtype=np.int64)
        new_index[order] = np.arange(count)
        faces = new_index[frame.faces.detach().cpu().numpy()][_hashed_order(num_faces, salts[1])]
        shift = (_splitmix(np.arange(num_faces, dtype=np.uint64) ^ salts[2]) % np.uint64(3)).astype(np.int64)
        faces = faces[np.arange(num_faces)[:, None], (np.arange(3)[None, :] + shift[:, None]) % 3]
        device = frame.verts.device
        verts = frame.verts[torch.from_numpy(order).to(device)]
        out.append(Mesh(verts, torch.from_numpy(faces).to(device), validate=False))
    return out


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

    Only the change is known here, not the other value: near a rounding boundary the other run can print another
    last digit with the same count of digits (8.9506e-07 and 8.9453e-07 print ``9.0e-07`` and ``8.9e-07``). The
    reports use :func:`shared_cell`, which has both values and prints the same text for both.

    Example:
        >>> determined_cell(0.0123456, 0.013, "#.2g"), determined_cell(0.0123456, 0.2, "#.2g")
        ('0.01', '~0.01')
        >>> determined_cell(-0.10612, 0.0, "#.3g"), determined_cell(61.27, 0.3, ".1f")
        ('-0.106', '61')
    """
    digits = determined_digits(change, spec)
    least = 1 if spec.endswith("g") else 0  # one significant digit; no decimal
    text = _cell_text(value, max(digits, least), least == 1)
    return text if digits >= least else f"~{text}"


def _cell_text(value: Any, digits: int, significant: bool) -> str:
    """``value`` with ``digits`` significant digits (``#`` kept, a bare point dropped) or decimals."""
    if significant:
        # '#' keeps a significant trailing zero (0.010); with one digit it leaves a bare point ("2.e-07", "3.").
        return format_number(value, f"#.{digits}g").replace(".e", "e").rstrip(".")
    return format_number(value, f".{digits}f")


def shared_cell(value: Any, other: Any, spec: str) -> str:
    """The text both of two runs print for a cell: the most digits of ``spec`` at which their values read the same.

    ``value`` (a run's) and ``other`` (the same figure in a second run, e.g. on nudged frames) are printed with the
    format's digits, then one digit fewer, down to one significant digit (no decimal for a fixed-point ``spec``),
    and the first count at which both texts are equal is kept. Unlike :func:`determined_cell`, which keeps as many
    digits as the change allows and can then print ``9.0e-07`` for one run and ``8.9e-07`` for the other, this text
    is the same whichever of the two values is ``value``. Where even one significant digit (a fixed-point format's
    integer part) differs, the cell is ``~`` and the midpoint with that one digit.

    Args:
        value: a real number (Python, NumPy or a 0-d tensor).
        other: the same figure in the second run.
        spec: the column's format: significant digits (``"#.2g"``) or decimals (``".1f"``).

    Returns:
        The cell's text; ``shared_cell(a, b, spec) == shared_cell(b, a, spec)`` for any ``a`` and ``b``.

    Example:
        >>> shared_cell(8.9506e-07, 8.9453e-07, "#.2g"), shared_cell(8.9453e-07, 8.9506e-07, "#.2g")
        ('9e-07', '9e-07')
        >>> shared_cell(0.012499, 0.012501, "#.2g"), shared_cell(0.0123, 0.0123, "#.2g")
        ('0.01', '0.012')
        >>> shared_cell(0.0123, 0.0283, "#.2g"), shared_cell(61.27, 61.36, ".1f"), shared_cell(60.9, 62.2, ".1f")
        ('~0.02', '61', '~62')
    """
    significant = spec.endswith("g")
    most = int(spec.rstrip("fg").split(".")[-1])
    for digits in range(most, 0 if significant else -1, -1):
        text = _cell_text(value, digits, significant)
        if text == _cell_text(other, digits, significant):
            return text
    midpoint = float(value) / 2 + float(other) / 2  # commutative: the same text from either run
    return "~" + _cell_text(midpoint, 1 if significant else 0, significant)


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
    """The change of every table cell between a run and a second run on nudged, relabelled frames.

    Attributes:
        rounding: the storage unit the frames were nudged by (:func:`storage_unit`).
        seed: the nudge's seed, and the relabelling's (:func:`relabel_frames`).
        changes: per table (``"I"`` .. ``"IV-reverse"``), per row in the table's order, per statistic: the change,
            relative to the larger magnitude for every statistic but ``psnr`` (absolute, dB).
        nudged: the second run's values, in the layout of ``changes``: a table found here prints each cell as both
            runs print it (:func:`shared_cell`); a table found only in ``changes`` keeps the digits its change
            leaves (:func:`determined_cell`, which near a rounding boundary can differ from the other run's).

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 3
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]  # every vertex 0.01 away
        >>> seq = evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)
        >>> d = measure_determinacy({"moved": seq}, {"moved": seq}, "float32")  # the same run twice: nothing moved
        >>> table_1 = d.changes["I"]
        >>> first_row = table_1[0]
        >>> d.rounding, list(d.changes)[:2], first_row["ave"]
        ('float32', ['I', 'II'], 0.0)
    """

    rounding: str
    seed: int
    changes: Mapping[str, list[dict[str, float]]]
    nudged: Mapping[str, list[dict[str, float]]] = field(default_factory=dict)

    def cell(self, table: str, row: int, key: str, value: Any, spec: str) -> str:
        """The cell of ``value`` with only the digits both runs print alike (at most those of ``spec``).

        With the second run's value (:attr:`nudged`): :func:`shared_cell`, the same text for either run. Without:
        a significant-digit ``spec`` (``"#.2g"``) keeps ``floor(-log10(relative change))`` digits, at least one; a
        fixed-point one (``".1f"``) keeps ``floor(-log10(absolute change))`` decimals, at least none. A cell whose
        first printed digit moved is prefixed with ``~``.

        Example:
            >>> d = Determinacy("float32", 0, {"I": [{"mse": 6e-4}]}, {"I": [{"mse": 8.9453e-07}]})
            >>> d.cell("I", 0, "mse", 8.9506e-07, "#.2g")  # 8.9e-07 in the other run: one digit is shared
            '9e-07'
            >>> d = Determinacy("float32", 0, {"III": [{"ave": 0.013, "psnr": 0.3}]})
            >>> d.cell("III", 0, "ave", 0.0123456, "#.2g"), d.cell("III", 0, "psnr", 61.27, ".1f")
            ('0.01', '61')
            >>> Determinacy("float32", 0, {"III": [{"ave": 0.2}]}).cell("III", 0, "ave", 0.0123456, "#.2g")
            '~0.01'
        """
        if table in self.nudged:
            return shared_cell(value, self.nudged[table][row][key], spec)
        return determined_cell(value, self.changes[table][row][key], spec)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: ``{"rounding", "seed", "changes": {table: [row: {statistic: change}]}}``, and ``"nudged"``.

        ``"nudged"`` (the second run's values, in the same layout) only where measured.
        """
        out: dict[str, Any] = {"rounding": self.rounding, "seed": self.seed}
        out["changes"] = {t: list(r) for t, r in self.changes.items()}
        if self.nudged:
            out["nudged"] = {t: list(r) for t, r in self.nudged.items()}
        return out


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
    values: dict[str, list[dict[str, float]]] = {}
    for table in _TABLES:
        rows, again = table_rows(methods, table, best=best), table_rows(nudged, table, best=best)
        changes[table] = row_changes([r[2] for r in rows], [r[2] for r in again])
        values[table] = row_values([r[2] for r in again])
    return Determinacy(storage_unit(rounding), seed, changes, values)


def row_values(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, float]]:
    """The statistics of the tables' columns of each row, as :attr:`Determinacy.nudged` holds them.

    Example:
        >>> stats = {"ave": 2.0, "var": 1.0, "std": 1.0, "mse": 5.0, "rmse": 2.2, "max": 4.0, "p95": 3.0, "psnr": 40.0}
        >>> row_values([{**stats, "median": 1.5}])[0] == stats
        True
    """
    from torchmeshmetric.evaluation.reports import COLUMNS

    return [{key: float(row[key]) for key, _ in COLUMNS} for row in rows]


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
    values = [{k: float(nudged[m][k]) for k in names} for m in figures]
    return Determinacy(
        determinacy.rounding,
        determinacy.seed,
        {**determinacy.changes, "temporal": rows},
        {**determinacy.nudged, "temporal": values},
    )
