"""The ``torchmeshmetric bdrate ANCHOR.csv TEST.csv`` command: BD-rate per metric column (no torch imported)."""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from torchmeshmetric._format import check_csv_fields, json_safe
from torchmeshmetric.cli.options import path_argument

__all__ = ["add_bdrate_command", "read_curve"]


def _number(path: str, lineno: int, column: str, text: str | None) -> float:
    try:
        return float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{path}:{lineno}: column {column!r}: expected a number, found {text!r}") from None


def _check_row(
    path: str, lineno: int, row: dict[str | None, Any], header: list[str], cols: dict[str, list[float]]
) -> None:
    check_csv_fields(path, lineno, row, header)
    for k in cols:
        value = _number(path, lineno, k, row[k])
        if k == "rate" and not (math.isfinite(value) and value > 0):
            raise ValueError(f"{path}:{lineno}: column 'rate': expected a positive finite rate, found {row[k]!r}")
        if k != "rate" and not math.isfinite(value):
            raise ValueError(f"{path}:{lineno}: column {k!r}: expected a finite PSNR, found {row[k]!r} "
                             "(clip identical frames first, as the ctc means do)")  # fmt: skip
        cols[k].append(value)


def _refuse_header(path: str, header: Sequence[str] | None) -> NoReturn:
    """A CSV that is no rate curve: the header found, and for the test model's CSV what to read instead.

    The test model's CSV (``ctc-campaign``'s ``anchor.csv`` and ``test.csv``, ``collect_results.sh``'s) is refused
    rather than read: it holds every sequence, condition and rate of a codec in one file, ``0`` for a colour figure
    not computed and ``inf`` for a lossless point, and its rate is the total bitstream, where the CTC sheet takes the
    rate from the bitstream components when the campaign has them. Its BD-rates, per sequence and condition with
    the sheet's rates, are ``ctc-campaign``'s summary (found by review O: the message named no header, no way out).
    """
    from torchmeshmetric.mpeg.ctc.sheet import TEST_MODEL_COLUMNS  # the standard library only: no torch

    expected = "expected a header with a 'rate' column and one column per metric (one row per rate point)"
    if not header:
        raise ValueError(f"{path}:1: {expected}, found an empty file")
    found = ",".join(header)
    if set(TEST_MODEL_COLUMNS[:5]) <= set(header):
        raise ValueError(
            f"{path}:1: {expected}, found the test model's CSV header {found!r} (as ctc-campaign writes anchor.csv "
            "and test.csv: every sequence, condition and rate of a codec): its BD-rates per sequence and condition, "
            "with the CTC sheet's rates, are ctc-campaign's summary.csv (summary.md, summary.json; in Python, from "
            "such CSVs: torchmeshmetric.mpeg.read_test_model_csv and ctc_summary); bdrate compares one curve per "
            "file (docs/ctc.md, 'BD-rates')"
        )
    raise ValueError(f"{path}:1: {expected}, found the header {found!r}")


def _text(data: bytes) -> str:
    """A CSV's text: UTF-8 (a byte-order mark dropped), or Latin-1 where it is not UTF-8, as the mesh readers read.

    A CSV exported by an older spreadsheet may hold a Latin-1 byte in a column name or a cell; read as Latin-1, such
    a byte reaches the checks as a character, and the message names its file, line and column (it was the codec's
    "'utf-8' codec can't decode byte 0xff in position 12", naming neither the file nor the line: review X, F2).
    """
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.removeprefix(b"\xef\xbb\xbf").decode("latin-1")


def _refuse_repeated_columns(path: str, header: Sequence[str]) -> None:
    """Refuse a header that names a column twice: which of the two is meant cannot be told.

    ``csv.DictReader`` keeps the last of two equal names and drops the first without a word: ``rate,GridD1,GridD1``
    gave the BD-rate of the third column (+100 % where the second gives 0 %: review X, F1), as the PLY reader refuses
    a property declared twice.
    """
    first: dict[str, int] = {}
    for column, name in enumerate(header, 1):
        if name in first:
            raise ValueError(
                f"{path}:1: column {name!r} appears twice in the header (columns {first[name]} and {column}); which "
                "of the two is meant cannot be told"
            )
        first[name] = column


def read_curve(path: str) -> dict[str, list[float]]:
    r"""The rate points of one CSV: ``{"rate": [...], metric: [...]}``, every value checked, errors as ``file:line``.

    A UTF-8 byte-order mark (spreadsheets write one) is accepted, and a file that is not UTF-8 is read as Latin-1 (as
    the mesh readers); no column may be named twice; every row must have the header's fields, positive rates and
    finite PSNRs; a metric needs 2 rate points or more with distinct PSNRs.

    Raises:
        ValueError: the first problem found, naming the file, the line and the column (a header without ``rate``:
            the header found; a column named twice; a file that cannot be read; the test model's CSV,
            ``ctc-campaign``'s ``anchor.csv``: where its BD-rates are).

    Example:
        >>> import tempfile, os
        >>> p = os.path.join(tempfile.mkdtemp(), "a.csv")
        >>> _ = open(p, "w").write("rate,GridD1\n100,30\n200,33\n")
        >>> read_curve(p)
        {'rate': [100.0, 200.0], 'GridD1': [30.0, 33.0]}
    """
    p = Path(path)
    try:
        if not p.is_file():
            raise ValueError(f"{path}: file not found" if not p.exists() else f"{path}: not a file")
        data = p.read_bytes()
    except OSError as exc:  # unreadable, or in a folder that cannot be searched
        raise ValueError(f"{path}: cannot read it ({(exc.strerror or str(exc)).lower()})") from exc
    with io.StringIO(_text(data), newline="") as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None or "rate" not in reader.fieldnames:
            _refuse_header(path, reader.fieldnames)
        _refuse_repeated_columns(path, reader.fieldnames)
        cols: dict[str, list[float]] = {k: [] for k in reader.fieldnames if k}
        lines: list[int] = []
        for row in reader:
            _check_row(path, reader.line_num, row, list(reader.fieldnames), cols)
            lines.append(reader.line_num)
    if len(lines) < 2:
        raise ValueError(f"{path}: expected at least 2 rate points (rows), found {len(lines)}")
    for k, values in cols.items():
        seen: dict[float, int] = {}
        for v, line in zip(values, lines, strict=True):
            if k != "rate" and v in seen:
                raise ValueError(f"{path}:{line}: column {k!r}: PSNR {v!r} repeats line {seen[v]}'s; BD-rate needs "
                                 "distinct PSNRs on a curve")  # fmt: skip
            seen.setdefault(v, line)
    return cols


def _run_bdrate(args: argparse.Namespace) -> int:
    from torchmeshmetric.mpeg.ctc.bd_rate import bd_rate

    a, b = read_curve(args.anchor), read_curve(args.test)
    metrics = [k for k in a if k != "rate" and k in b]
    if not metrics:
        raise ValueError(f"{args.test}: no metric column in common with {args.anchor}")
    out = {m: bd_rate(a["rate"], a[m], b["rate"], b[m]) for m in metrics}
    if args.json:
        print(json.dumps(json_safe({"bd_rate": out}), indent=1))
    else:
        width = max(len(m) for m in metrics)
        for m in metrics:
            print(f"{m.ljust(width)}  {out[m]:+.4f} %")
    return 0


def add_bdrate_command(sub: Any) -> None:
    """Add the ``bdrate`` subcommand to the CLI's subparsers."""
    p = sub.add_parser(
        "bdrate",
        help="BD-rate of a test codec against an anchor (the CTC spreadsheet's bdRateExtend), per metric",
        description="Bjontegaard delta rate in percent of TEST against ANCHOR, per metric column present in both "
        "CSVs (a 'rate' column and one PSNR column per metric, one row per rate point): log10(rate) as a piecewise "
        "cubic Hermite function of PSNR (the CTC spreadsheet's bdRateExtend: its slopes, no monotonicity clamp), "
        "integrated exactly over the overlapping PSNR range; +-100 when the curves do not overlap. Negative = TEST "
        "needs less rate for the same quality.",
    )
    p.add_argument("anchor", type=path_argument, metavar="ANCHOR.csv", help="the anchor's rate points")
    p.add_argument("test", type=path_argument, metavar="TEST.csv", help="the tested codec's rate points")
    p.add_argument("--json", action="store_true", help='print {"bd_rate": {"GridD1": percent, ...}}')
    p.set_defaults(func=_run_bdrate, without_torch=True)
