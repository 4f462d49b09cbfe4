"""The V-DMC CTC spreadsheet: the test model's CSV rows and what ``scripts/results/empty.xlsm`` computes from them.

The test model's ``scripts/collect_results.sh`` appends one row per (sequence, condition, rate) to a CSV with the
columns of :data:`TEST_MODEL_COLUMNS`: the sequence means mmetric prints (9 significant digits; ``0`` for a colour
figure it did not compute), the bitstream size in bits, the encoder's output face count, runtimes and peak memory
(MB). The spreadsheet (the formulas of the public mirror's ``empty.xlsm``, sheets ``C0 lossless AI``, ``C1 lossy
AI``, ``C2 lossy RA`` and ``Summary``) then computes, per codec and rate row:

* ``Rate [Mbps] = TotalBitstreamBits * fps / frames / 1e6`` and ``bpif = TotalBitstreamBits / input faces`` (the
  source faces summed over the frames);
* the *total* bits ``L = M + texture + metadata`` with the geometry bits ``M = mesh intra + mesh inter +
  displacements`` (when the five components are known; otherwise the total bitstream);

per sequence (its rate rows, test ``B`` against anchor ``A``; :func:`~torchmeshmetric.mpeg.ctc.bd_rate.bd_rate`):

* **BD-rate** of every metric against ``L``; **BD-TotGeoRate** of D1, D2 and IBSM-geom against ``M``;
  **BD-AttrRate** of luma, Cb, Cr and IBSM-luma against the texture bits;
* per rate row, each component's ratio ``B / A - 1`` (``0`` when ``B`` is 0, as the sheet's ``IF``);

and per class and overall: the mean over sequences of each BD figure, the mean over rate rows of the bpif and of
the component ratios, and ``sum(B time) / sum(A time)`` for encoder and decoder runtimes. As the sheet's
``AVERAGE`` over a range that holds an error, a mean (or sum ratio) over cells of which one cannot be computed (a
BD figure of a flat curve, an anchor component of 0, an unknown runtime) cannot be computed either. Lossless
conditions (one rate) give the bpif ratio ``mean B bpif / mean A bpif`` and the mesh-bits ratio ``B / A - 1``.
Beyond the sheet: the same sum ratio for peak memory, and every ratio at sequence and class scope too.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from torchmeshmetric._format import check_csv_fields, markdown_cell
from torchmeshmetric.mpeg.ctc.bd_rate import bd_rate

__all__ = [
    "BD_ATTRIBUTE",
    "BD_GEOMETRY",
    "COMPONENTS",
    "RatePoint",
    "SheetCondition",
    "SheetSequence",
    "TEST_MODEL_COLUMNS",
    "ctc_summary",
    "format_test_model_csv",
    "read_test_model_csv",
    "summary_csv",
    "summary_markdown",
]

_METRICS = ("GridD1", "GridD2", "GridLuma", "GridChromaCb", "GridChromaCr", "IbsmGeom", "IbsmLuma")

TEST_MODEL_COLUMNS = (
    "SeqId",
    "CondId",
    "RateId",
    "NbOutputFaces",
    "TotalBitstreamBits",
    *_METRICS,
    "UserEncoderRuntime",
    "UserDecoderRuntime",
    "PeakEncoderMemory",
    "PeakDecoderMemory",
)
"""The CSV columns ``collect_results.sh`` writes, in its order."""

COMPONENTS = ("mesh_intra", "mesh_inter", "displacements", "texture", "metadata")
"""The bitstream components of the sheet (columns ``Bmesh Intra``, ``Bmesh Inter``, ``Disp``, ``Texture``,
``MetaData``), in bits."""

BD_GEOMETRY = ("GridD1", "GridD2", "IbsmGeom")
"""The metrics of BD-TotGeoRate (against the geometry bits)."""

BD_ATTRIBUTE = ("GridLuma", "GridChromaCb", "GridChromaCr", "IbsmLuma")
"""The metrics of BD-AttrRate (against the texture bits)."""

_GEOMETRY_PARTS = ("mesh_intra", "mesh_inter", "displacements")


@dataclass(frozen=True)
class RatePoint:
    """One row of the test model's CSV: a codec's (sequence, condition, rate).

    Attributes:
        seq_id, cond_id, rate_id: ``SeqId``, ``CondId``, ``RateId``.
        total_bits: ``TotalBitstreamBits``.
        figures: metric column -> sequence mean (dB), as the CSV holds it; a figure not computed is absent.
        output_faces: ``NbOutputFaces`` (``None``: unknown).
        encoder_seconds, decoder_seconds: ``UserEncoderRuntime``, ``UserDecoderRuntime``.
        encoder_memory, decoder_memory: ``PeakEncoderMemory``, ``PeakDecoderMemory`` (MB).
        components: component name (:data:`COMPONENTS`) -> bits; empty when the split is unknown.

    Example:
        >>> import os, tempfile
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     path = os.path.join(folder, "anchor.csv")
        ...     with open(path, "w") as f:
        ...         _ = f.write(format_test_model_csv([RatePoint(1, 1, 2, 8000, {"GridD1": 70.5})]))
        ...     point = read_test_model_csv(path)[1, 1, 2]
        >>> point.total_bits, point.figures, point.output_faces
        (8000.0, {'GridD1': 70.5}, None)
    """

    seq_id: int
    cond_id: int
    rate_id: int
    total_bits: float
    figures: dict[str, float] = field(default_factory=dict)
    output_faces: int | None = None
    encoder_seconds: float | None = None
    decoder_seconds: float | None = None
    encoder_memory: float | None = None
    decoder_memory: float | None = None
    components: dict[str, float] = field(default_factory=dict)

    @property
    def key(self) -> tuple[int, int, int]:
        """``(seq_id, cond_id, rate_id)``."""
        return self.seq_id, self.cond_id, self.rate_id

    def geometry_bits(self) -> float | None:
        """The sheet's ``M``: mesh intra + mesh inter + displacements (``None`` without the split)."""
        if not all(c in self.components for c in _GEOMETRY_PARTS):
            return None
        return self.components["mesh_intra"] + self.components["mesh_inter"] + self.components["displacements"]

    def sheet_bits(self) -> float:
        """The sheet's ``L`` (the BD-rate's rate): ``M + texture + metadata``, or the total bitstream without split."""
        m = self.geometry_bits()
        if m is None or "texture" not in self.components or "metadata" not in self.components:
            return self.total_bits
        return m + self.components["texture"] + self.components["metadata"]


@dataclass(frozen=True)
class SheetSequence:
    """What the sheet knows of a sequence (its columns Class, Sequence, № input faces, № frames, Frame rate).

    Attributes:
        seq_id: ``SeqId``.
        name: the sequence's name.
        cls: its class (``cat1-A``...).
        frames: frames encoded.
        fps: frame rate.
        input_faces: the source's faces summed over those frames.
    """

    seq_id: int
    name: str
    cls: str
    frames: int
    fps: float
    input_faces: int


@dataclass(frozen=True)
class SheetCondition:
    """A condition of the sheet: ``CondId``, its name (``C1 lossy AI``) and whether it is lossless."""

    cond_id: int
    name: str
    lossless: bool = False


# --------------------------------------------------------------------------------------------------- the CSV


def _csv_number(x: float | int | None, integer: bool = False) -> str:
    if x is None:
        return ""
    if integer and float(x).is_integer():
        return str(int(x))
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return format(float(x), ".9g")  # mmetric prints 9 significant digits; the script copies them


def format_test_model_csv(points: Iterable[RatePoint]) -> str:
    """The CSV ``collect_results.sh`` writes: header, then one row per point (figures as mmetric prints them).

    A metric column the chain did not compute is written ``0`` for the grid colour figures (mmetric prints a mean of
    0) and left empty for IBSM (mmetric prints no line). Unknown runtimes, memory or face counts are empty.

    Example:
        >>> print(format_test_model_csv([RatePoint(1, 1, 1, 8000, {"GridD1": 70.123456789}, 10)]).splitlines()[1])
        1,1,1,10,8000,70.1234568,,0,0,0,,,,,,
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(TEST_MODEL_COLUMNS)
    for p in points:
        figs = []
        for m in _METRICS:
            if m in p.figures:
                figs.append(_csv_number(p.figures[m]))
            else:
                figs.append("0" if m in ("GridLuma", "GridChromaCb", "GridChromaCr") and "GridD1" in p.figures else "")
        w.writerow(
            [
                p.seq_id,
                p.cond_id,
                p.rate_id,
                _csv_number(p.output_faces, True),
                _csv_number(p.total_bits, True),
                *figs,
                _csv_number(p.encoder_seconds),
                _csv_number(p.decoder_seconds),
                _csv_number(p.encoder_memory),
                _csv_number(p.decoder_memory),
            ]
        )
    return buf.getvalue()


def _field(path: str, line: int, row: Mapping[str, str | None], col: str, *, required: bool) -> float | None:
    text = (row.get(col) or "").strip()
    if text == "":
        if required:
            raise ValueError(f"{path}:{line}: column {col!r} is empty")
        return None
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{path}:{line}: column {col!r}: expected a number, found {text!r}") from None
    if math.isnan(value):
        raise ValueError(f"{path}:{line}: column {col!r}: expected a number, found {text!r}")
    return value


def read_test_model_csv(path: str | Path) -> dict[tuple[int, int, int], RatePoint]:
    r"""The rows of a CSV the test model's scripts wrote, by ``(SeqId, CondId, RateId)``.

    ``-1`` (the script's mark of a failed lossless check) and empty fields read as unknown; a metric of ``0``
    (mmetric's mean of a figure it did not compute) as absent.

    Args:
        path: the CSV file (UTF-8, a byte-order mark allowed); its header names the test model's columns
            (``SeqId``, ``CondId``, ``RateId``, ``TotalBitstreamBits``, the metrics, ...).

    Returns:
        ``(seq_id, cond_id, rate_id)`` → :class:`RatePoint`, in file order.

    Raises:
        ValueError: a missing file or column, a row with more or fewer fields than the header (a row cut
            mid-write), a non-numeric field, a repeated row (naming file:line).

    Example:
        >>> import tempfile, os
        >>> p = os.path.join(tempfile.mkdtemp(), "a.csv")
        >>> _ = open(p, "w").write(format_test_model_csv([RatePoint(1, 1, 2, 8000, {"GridD1": 70.5})]))
        >>> read_test_model_csv(p)[1, 1, 2].figures
        {'GridD1': 70.5}
    """
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{path}: file not found" if not p.exists() else f"{path}: not a file")
    out: dict[tuple[int, int, int], RatePoint] = {}
    with open(p, newline="", encoding="utf-8-sig") as fh:
        reader = csv.DictReader(fh)
        # The test model's collect_results.sh writes its newer header with a trailing space after
        # "PeakDecoderMemory": unstripped, that column was never read (decoder memory always unknown).
        reader.fieldnames = [name.strip() for name in reader.fieldnames or []]
        missing = [c for c in TEST_MODEL_COLUMNS[:5] if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(
                f"{path}:1: expected the test model's header (SeqId, CondId, RateId, ...); missing {missing[0]!r}"
            )
        for row in reader:
            line = reader.line_num
            check_csv_fields(path, line, row, reader.fieldnames or [])  # a row cut mid-write, or shifted
            seq, cond, rate = (int(_field(str(p), line, row, c, required=True) or 0) for c in TEST_MODEL_COLUMNS[:3])
            v = {c: _field(str(p), line, row, c, required=False) if c in row else None for c in TEST_MODEL_COLUMNS[3:]}
            known = {c: x for c, x in v.items() if x is not None and x >= 0}
            if known.get("TotalBitstreamBits") == 0:  # a coded point has bits; 0 would drop its BD figures silently
                raise ValueError(f"{path}:{line}: column 'TotalBitstreamBits': a coded point has bits, found 0")
            figures = {m: known[m] for m in _METRICS if known.get(m, 0) != 0}
            faces = known.get("NbOutputFaces")
            point = RatePoint(
                seq,
                cond,
                rate,
                known.get("TotalBitstreamBits", math.nan),
                figures,
                None if faces is None else int(faces),
                known.get("UserEncoderRuntime"),
                known.get("UserDecoderRuntime"),
                known.get("PeakEncoderMemory"),
                known.get("PeakDecoderMemory"),
            )
            if point.key in out:
                raise ValueError(f"{path}:{line}: SeqId {seq}, CondId {cond}, RateId {rate} repeats an earlier row")
            out[point.key] = point
    return out


# ------------------------------------------------------------------------------------------------ the summary


def _average(cells: Iterable[tuple[str, float | None]]) -> tuple[float | None, list[str]]:
    """The sheet's ``AVERAGE`` over cells that are all computable, and the labels of those that are not.

    A cell that cannot be computed is the sheet's error (``#DIV/0!``, ``#VALUE!``), and ``AVERAGE`` over a range
    holding an error is itself an error: the mean is ``None`` as soon as one cell is, never the mean of the others.
    """
    cells = list(cells)
    lacking = [label for label, v in cells if v is None]
    if lacking or not cells:
        return None, lacking
    return math.fsum(v for _, v in cells if v is not None) / len(cells), []


def _ratio_of_sums(cells: Iterable[tuple[str, float | None, float | None]]) -> tuple[float | None, list[str]]:
    """``SUM(B) / SUM(A)`` over ``(label, B, A)`` rows, and the labels of the rows where B or A is unknown.

    A row with an unknown value makes the ratio not computable (``None``): the sheet would read the empty cell as 0
    and give a ratio of unequal row sets. ``None`` too when the anchor's sum is 0.
    """
    cells = list(cells)
    lacking = [label for label, x, y in cells if x is None or y is None]
    if lacking or not cells:
        return None, lacking
    den = math.fsum(y for _, _, y in cells if y is not None)
    return (math.fsum(x for _, x, _ in cells if x is not None) / den if den != 0 else None), []


def _component_ratio(b: RatePoint, a: RatePoint, name: str) -> float | None:
    """``IF(B = 0, 0, B / A - 1)``; ``None`` when unknown or when the anchor's is 0 (the sheet's #DIV/0!)."""
    if name not in b.components or name not in a.components:
        return None
    if b.components[name] == 0:
        return 0.0
    if a.components[name] == 0:
        return None
    return b.components[name] / a.components[name] - 1


def _bd(
    a: Sequence[RatePoint], b: Sequence[RatePoint], metric: str, bits: Callable[[RatePoint], float | None]
) -> float | None:
    """One BD figure of a sequence; ``None`` when a curve lacks the metric, the rates, or 2 distinct finite PSNRs."""
    rates_a, rates_b = [bits(p) for p in a], [bits(p) for p in b]
    if any(r is None or math.isnan(r) for r in (*rates_a, *rates_b)):
        return None
    if not all(metric in p.figures for p in (*a, *b)) or len(a) < 2 or len(b) < 2:
        return None
    try:
        return bd_rate(rates_a, [p.figures[metric] for p in a], rates_b, [p.figures[metric] for p in b])  # type: ignore[arg-type]
    except ValueError:  # a curve without 2 distinct finite PSNRs (99.99 everywhere, lossless inf): the sheet's error
        return None


def _texture_bits(p: RatePoint) -> float | None:
    return p.components.get("texture")


def _rows(seq: SheetSequence, a: RatePoint, b: RatePoint) -> dict[str, Any]:
    def side(p: RatePoint) -> dict[str, Any]:
        return {
            "rate_mbps": p.total_bits * seq.fps / seq.frames / 1e6,
            "bpif": p.total_bits / seq.input_faces,
            "total_bits": p.total_bits,
            "sheet_bits": p.sheet_bits(),
            "geometry_bits": p.geometry_bits(),
            "texture_bits": _texture_bits(p),
            **p.figures,
        }

    return {
        "rate": a.rate_id,
        "anchor": side(a),
        "test": side(b),
        "component_ratios": {c: _component_ratio(b, a, c) for c in COMPONENTS},
    }


def _scope(
    rows: list[tuple[SheetSequence, RatePoint, RatePoint]], bd: list[tuple[str, dict[str, Any]]], lossless: bool
) -> dict[str, Any]:
    """The aggregate figures of a set of rate rows (a sequence, a class, the whole condition).

    ``bd`` holds each sequence's name and BD figures. ``not_computable`` maps a summary column
    (``bd_rate:GridD1``, ``time_ratios:encoder``...) whose aggregate is ``None`` although some of its cells were
    computed to the cells that were not (sequence names, or ``<sequence> rate <RateId>`` for per-row figures).
    """
    lacking: dict[str, list[str]] = {}

    def keep(column: str, result: tuple[float | None, list[str]], n: int) -> float | None:
        value, missing = result
        if missing and len(missing) < n:  # some cells computed, some not: say which are missing
            lacking[column] = missing
        return value

    labelled = [(f"{s.name} rate {a.rate_id}", s, a, b) for s, a, b in rows]
    n = len(labelled)
    bpif_a, _ = _average((lb, a.total_bits / s.input_faces) for lb, s, a, _ in labelled)
    bpif_b, _ = _average((lb, b.total_bits / s.input_faces) for lb, s, _, b in labelled)

    def sums(kind: str, attr: str) -> float | None:
        cells = [(lb, getattr(b, attr), getattr(a, attr)) for lb, _, a, b in labelled]
        return keep(f"{kind}:{attr.split('_')[0]}", _ratio_of_sums(cells), n)

    out: dict[str, Any] = {
        "bpif": {"anchor": bpif_a, "test": bpif_b},
        "bpif_ratio": bpif_b / bpif_a if bpif_a and bpif_b is not None else None,
        "component_ratios": {
            c: keep(f"component_ratios:{c}", _average((lb, _component_ratio(b, a, c)) for lb, _, a, b in labelled), n)
            for c in COMPONENTS
        },
        "time_ratios": {
            "encoder": sums("time_ratios", "encoder_seconds"),
            "decoder": sums("time_ratios", "decoder_seconds"),
        },
        "memory_ratios": {
            "encoder": sums("memory_ratios", "encoder_memory"),
            "decoder": sums("memory_ratios", "decoder_memory"),
        },
    }
    if lossless:
        mesh = [
            (lb, _sum_parts(b, ("mesh_intra", "mesh_inter")), _sum_parts(a, ("mesh_intra", "mesh_inter")))
            for lb, _, a, b in labelled
        ]
        out["mesh_ratio"] = keep(
            "mesh_ratio", _average((lb, x / y - 1 if x is not None and y else None) for lb, x, y in mesh), n
        )
    else:
        for kind in ("bd_rate", "bd_geometry_rate", "bd_attribute_rate"):
            keys = {m for _, d in bd for m in d[kind]}
            out[kind] = {
                m: keep(f"{kind}:{m}", _average((name, d[kind].get(m)) for name, d in bd), len(bd))
                for m in _METRICS
                if m in keys
            }
    out["not_computable"] = lacking
    return out


def _sum_parts(p: RatePoint, parts: tuple[str, ...]) -> float | None:
    return math.fsum(p.components[c] for c in parts) if all(c in p.components for c in parts) else None


def ctc_summary(
    sequences: Sequence[SheetSequence],
    conditions: Sequence[SheetCondition],
    anchor: Mapping[tuple[int, int, int], RatePoint],
    test: Mapping[tuple[int, int, int], RatePoint],
    *,
    names: tuple[str, str] = ("anchor", "test"),
) -> dict[str, Any]:
    """The CTC sheet's figures of a test codec against an anchor (see the module for the formulas).

    Args:
        sequences: the sequences, in the sheet's order (classes are averaged in order of first appearance).
        conditions: the conditions.
        anchor: the anchor's rows by ``(seq_id, cond_id, rate_id)`` (:func:`read_test_model_csv`).
        test: the tested codec's rows.
        names: the two codecs' names (the sheet's ``Reference`` and ``Tested``).

    Returns:
        ``{"anchor", "test", "conditions": [{"id", "name", "lossless", "sequences": [{"id", "name", "class",
        "rates": [...], <aggregates>}], "classes": [{"class", <aggregates>}], "overall": {<aggregates>}}]}``; the
        aggregates are ``bpif``, ``bpif_ratio``, ``component_ratios``, ``time_ratios``, ``memory_ratios`` and
        ``bd_rate``, ``bd_geometry_rate``, ``bd_attribute_rate`` (metric -> percent) or, lossless, ``mesh_ratio``.
        Figures that cannot be computed (a missing row, component, runtime or metric) are ``None``; rates present
        in one codec only are left out. An average or sum ratio over cells of which one cannot be computed is
        ``None`` too (the sheet's ``AVERAGE`` of a range holding an error is an error), and the scope's
        ``not_computable`` (column -> the sequences or ``<sequence> rate <id>`` rows lacking it) says which cells
        lacked it.

    Example:
        >>> s = [SheetSequence(1, "a", "cat1-A", 2, 30.0, 1000)]
        >>> a = {(1, 1, r): RatePoint(1, 1, r, 1000.0 * r, {"GridD1": 60.0 + r}) for r in (1, 2, 3)}
        >>> b = {(1, 1, r): RatePoint(1, 1, r, 500.0 * r, {"GridD1": 60.0 + r}) for r in (1, 2, 3)}
        >>> d = ctc_summary(s, [SheetCondition(1, "C1 lossy AI")], a, b)
        >>> overall = d["conditions"].pop()["overall"]
        >>> bd = overall["bd_rate"]
        >>> round(bd["GridD1"], 9)
        -50.0
    """
    out: dict[str, Any] = {"anchor": names[0], "test": names[1], "conditions": []}
    for cond in conditions:
        per_seq = []
        all_rows: list[tuple[SheetSequence, RatePoint, RatePoint]] = []
        classes: dict[str, tuple[list[Any], list[tuple[str, dict[str, Any]]]]] = {}
        for seq in sequences:
            rate_ids = sorted(
                {k[2] for k in anchor if k[:2] == (seq.seq_id, cond.cond_id)}
                & {k[2] for k in test if k[:2] == (seq.seq_id, cond.cond_id)}
            )
            if not rate_ids:
                continue
            a = [anchor[seq.seq_id, cond.cond_id, r] for r in rate_ids]
            b = [test[seq.seq_id, cond.cond_id, r] for r in rate_ids]
            rows = [(seq, x, y) for x, y in zip(a, b, strict=True)]
            bd: dict[str, Any] = {"bd_rate": {}, "bd_geometry_rate": {}, "bd_attribute_rate": {}}
            if not cond.lossless:
                bd["bd_rate"] = {m: _bd(a, b, m, RatePoint.sheet_bits) for m in _METRICS}
                bd["bd_geometry_rate"] = {m: _bd(a, b, m, RatePoint.geometry_bits) for m in BD_GEOMETRY}
                bd["bd_attribute_rate"] = {m: _bd(a, b, m, _texture_bits) for m in BD_ATTRIBUTE}
            rate_rows = [_rows(seq, x, y) for _, x, y in rows]
            per_seq.append(
                {
                    "id": seq.seq_id,
                    "name": seq.name,
                    "class": seq.cls,
                    "rates": rate_rows,
                    **_scope(rows, [(seq.name, bd)], cond.lossless),
                }
            )
            all_rows += rows
            cls_rows, cls_bd = classes.setdefault(seq.cls, ([], []))
            cls_rows += rows
            cls_bd.append((seq.name, bd))
        out["conditions"].append(
            {
                "id": cond.cond_id,
                "name": cond.name,
                "lossless": cond.lossless,
                "sequences": per_seq,
                "classes": [{"class": c, **_scope(r, bd_list, cond.lossless)} for c, (r, bd_list) in classes.items()],
                "overall": _scope(all_rows, [bd for _, bd_list in classes.values() for bd in bd_list], cond.lossless)
                if all_rows
                else {},
            }
        )
    return out


# ------------------------------------------------------------------------------------------------ the reports

_SUMMARY_COLUMNS = (
    *(f"bd_rate:{m}" for m in _METRICS),
    *(f"bd_geometry_rate:{m}" for m in BD_GEOMETRY),
    *(f"bd_attribute_rate:{m}" for m in BD_ATTRIBUTE),
    "bpif:anchor",
    "bpif:test",
    "bpif_ratio",
    "mesh_ratio",
    *(f"component_ratios:{c}" for c in COMPONENTS),
    "time_ratios:encoder",
    "time_ratios:decoder",
    "memory_ratios:encoder",
    "memory_ratios:decoder",
)


def _value(scope: Mapping[str, Any], column: str) -> float | None:
    parts = column.split(":")
    v: Any = scope
    for p in parts:
        if not isinstance(v, Mapping) or p not in v:
            return None
        v = v[p]
    return v if isinstance(v, (int, float)) else None


def _scopes(summary: Mapping[str, Any]) -> Iterable[tuple[Mapping[str, Any], str, str, str, Mapping[str, Any]]]:
    """``(condition, scope, name, class, figures)`` of every sequence, class and overall row."""
    for cond in summary["conditions"]:
        for s in cond["sequences"]:
            yield cond, "sequence", s["name"], s["class"], s
        for c in cond["classes"]:
            yield cond, "class", c["class"], c["class"], c
        if cond["overall"]:
            yield cond, "overall", "overall", "", cond["overall"]


def summary_csv(summary: Mapping[str, Any]) -> str:
    """The summary as CSV: one row per condition and sequence, class average and overall average.

    Columns ``condition, scope, name, class`` then :data:`_SUMMARY_COLUMNS` (BD figures in percent, ratios as
    fractions: ``-0.1`` is 10 % fewer bits; time and memory ratios ``B / A``), full precision, empty when unknown.
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["condition", "scope", "name", "class", *_SUMMARY_COLUMNS])
    for cond, scope, name, cls, figs in _scopes(summary):
        cells = ["" if (v := _value(figs, c)) is None else repr(float(v)) for c in _SUMMARY_COLUMNS]
        w.writerow([cond["name"], scope, name, cls, *cells])
    return buf.getvalue()


def _pct(v: float | None, scale: float = 1.0) -> str:
    return "·" if v is None else f"{v * scale:+.2f} %"


def _label(scope: str, name: str) -> str:
    """A row's label in the summary's tables: the sequence's or class's name (escaped: the sheet's), or "Overall"."""
    cell = markdown_cell(name)
    return cell if scope == "sequence" else f"**{cell} average**" if scope == "class" else "**Overall average**"


def summary_markdown(summary: Mapping[str, Any]) -> str:
    """The summary as Markdown tables, per condition: BD-rates, BD-TotGeoRate and BD-AttrRate, bpif and ratios."""
    out = [f"# V-DMC CTC summary: {summary['test']} against {summary['anchor']}", ""]
    for cond in summary["conditions"]:
        out += [f"## {cond['name']}", ""]
        rows = [(scope, name, figs) for c, scope, name, _, figs in _scopes(summary) if c is cond]
        if not cond["lossless"]:
            for kind, title, metrics in (
                ("bd_rate", "BD-rate", _METRICS),
                ("bd_geometry_rate", "BD-TotGeoRate", BD_GEOMETRY),
                ("bd_attribute_rate", "BD-AttrRate", BD_ATTRIBUTE),
            ):
                cols = [m for m in metrics if any(_value(f, f"{kind}:{m}") is not None for _, _, f in rows)]
                if not cols:
                    continue
                out += [f"### {title} [%]", "", "| | " + " | ".join(cols) + " |", "|---|" + "---:|" * len(cols)]
                for scope, name, f in rows:
                    label = _label(scope, name)
                    out.append(f"| {label} | " + " | ".join(_pct(_value(f, f"{kind}:{m}")) for m in cols) + " |")
                out.append("")
        cols = [
            "bpif A",
            "bpif B",
            "bpif ratio",
            # a lossless condition's mesh-bits ratio B / A - 1 (summary.csv and .json had it, the Markdown not:
            # review R #11)
            *(["mesh ratio"] if cond["lossless"] else []),
            *(c.replace("_", " ") for c in COMPONENTS),
            "enc time",
            "dec time",
            "enc memory",
            "dec memory",
        ]
        out += ["### Bits and complexity", "", "| | " + " | ".join(cols) + " |", "|---|" + "---:|" * len(cols)]
        for scope, name, f in rows:
            label = _label(scope, name)
            bp = [_value(f, "bpif:anchor"), _value(f, "bpif:test")]
            cells = ["·" if v is None else f"{v:.4f}" for v in bp]
            ratio = _value(f, "bpif_ratio")
            cells.append("·" if ratio is None else f"{ratio * 100:.2f} %")
            if cond["lossless"]:
                cells.append(_pct(_value(f, "mesh_ratio"), 100))
            cells += [_pct(_value(f, f"component_ratios:{c}"), 100) for c in COMPONENTS]
            for k in ("time_ratios:encoder", "time_ratios:decoder", "memory_ratios:encoder", "memory_ratios:decoder"):
                v = _value(f, k)
                cells.append("·" if v is None else f"{v * 100:.1f} %")
            out.append(f"| {label} | " + " | ".join(cells) + " |")
        out.append("")
        notes = [
            f"- {_label(scope, name)}, `{column}`: not computable for " + ", ".join(markdown_cell(x) for x in missing)
            for scope, name, f in rows
            for column, missing in f.get("not_computable", {}).items()
        ]
        if notes:
            out += ["· in a row computed from several cells: one of them could not be computed", "", *notes, ""]
    out += [
        "BD figures: the CTC sheet's bdRateExtend (pchip from 3 rate points; with 2, end slopes twice the secant) "
        "over the sequence's rate points; class and overall: the mean over sequences. Component ratios: test / "
        "anchor - 1 per rate, averaged over rates; time and memory: "
        "sum over rates of the test's over the anchor's. · : not computable (missing rows, components, runtimes or "
        "metrics; an average or sum over cells of which one is not computable).",
        "",
    ]
    return "\n".join(out)
