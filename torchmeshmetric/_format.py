"""Numbers as the package writes them: one formatter for tables, one JSON cleaner for reports.

The field-count check of the CSV rows it reads back is here too.

A leaf module (standard library only), used by the reports, the comparisons, the campaign tables and the commands.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["check_csv_fields", "format_number", "json_safe", "markdown_cell", "plain_label"]


def format_number(value: Any, spec: str = ".4g", *, small_spec: str | None = None) -> str:
    """A table cell: a float with the format ``spec``, non-finite values as ``nan``, ``inf``, ``-inf``.

    Args:
        value: a real number (Python, NumPy or a 0-d tensor), or anything else (written with ``str``: ints, names).
        spec: the format of a finite float (``".4g"``: 4 significant digits, the paper's tables).
        small_spec: the format of a finite float below ``1e-3`` in magnitude (``None``: ``spec``), for columns whose
            fixed-point format would round small errors to zero.

    Example:
        >>> format_number(0.0123456), format_number(float("nan")), format_number(-math.inf, ".4f")
        ('0.01235', 'nan', '-inf')
        >>> format_number(2.5e-5, ".4f", small_spec=".6g"), format_number(3)
        ('2.5e-05', '3')
    """
    if isinstance(value, (bool, int, str)) or not hasattr(value, "__float__"):
        return str(value)
    x = float(value)
    if not math.isfinite(x):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return format(x, small_spec if small_spec is not None and abs(x) < 1e-3 else spec)


def json_safe(value: Any) -> Any:
    """Non-finite floats replaced by the strings ``"inf"``, ``"-inf"``, ``"nan"`` (strict JSON has no infinity).

    Walks dicts, lists and tuples (tuples become lists, as ``json`` writes them).

    Example:
        >>> json_safe({"a": float("inf"), "b": [1.0, float("nan")]})
        {'a': 'inf', 'b': [1.0, 'nan']}
    """
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


#: The characters of a name that change how a Markdown cell renders (GitHub-flavoured): ``\`` escapes, ``|`` splits
#: the row, ``*`` ``_`` ``~`` are emphasis and strikethrough, a backtick code, ``[`` ``]`` a link (``![`` an image),
#: ``<`` ``>`` HTML or an autolink, ``$`` GitHub's math, ``&`` an entity (``&amp;`` shows as ``&``; only where one
#: follows). A ``_`` between two letters or digits is left alone: CommonMark's flanking rules never let it open or
#: close emphasis, so ``orig_qem`` is written as it is.
_MARKDOWN_SPECIAL = re.compile(r"[\\|*`\[\]<>~$]|&(?=#?\w+;)|(?<![^\W_])_|_(?![^\W_])")


def markdown_cell(text: object) -> str:
    r"""A user's name (a method's, a sequence's) as Markdown table cell text that renders as the name itself.

    Every character that Markdown would read as markup (:data:`_MARKDOWN_SPECIAL`) gets a backslash (CommonMark's
    escape of ASCII punctuation); line breaks become spaces. A ``|`` otherwise split its row into one cell more
    than the header has, and ``**a**`` or ``_a_`` showed in bold or italics. A name without such characters is
    written unchanged.

    Example:
        >>> markdown_cell("QEM | 50 %"), markdown_cell("a\nb"), markdown_cell("C:\\x")
        ('QEM \\| 50 %', 'a b', 'C:\\\\x')
        >>> print(markdown_cell("**a** _b_ [c](d) <e> orig_qem"))
        \*\*a\*\* \_b\_ \[c\](d) \<e\> orig_qem
    """
    return " ".join(_MARKDOWN_SPECIAL.sub(lambda m: "\\" + m.group(0), str(text)).splitlines())


def check_csv_fields(path: object, line: int, row: Mapping[str | None, Any], header: Sequence[str]) -> None:
    r"""Refuse a ``csv.DictReader`` row whose field count differs from its header's (a truncated or shifted row).

    ``DictReader`` fills a short row's missing fields with ``None`` and keeps a long row's extra fields under the key
    ``None``: either would otherwise read as empty cells or be dropped without a word.

    Raises:
        ValueError: ``"<path>:<line>: expected <n> fields (the header's), found <m>"``.

    Example:
        >>> import csv, io
        >>> r = csv.DictReader(io.StringIO("a,b,c\n1,2\n"))
        >>> check_csv_fields("x.csv", 2, next(r), r.fieldnames)
        Traceback (most recent call last):
        ...
        ValueError: x.csv:2: expected 3 fields (the header's), found 2
    """
    extra = row.get(None) or []
    found = sum(1 for k in header if row.get(k) is not None) + len(extra)
    if found != len(header):
        raise ValueError(f"{path}:{line}: expected {len(header)} fields (the header's), found {found}")


def plain_label(text: object) -> str:
    r"""A user's name as a matplotlib label (legend, title, axis), drawn as written: every ``$`` escaped.

    Matplotlib parses the text between two unescaped ``$`` as mathtext: ``budget $5 to $10`` was drawn as math
    italics ``budget 5 to 10``, and ``a_$b_$c`` raised a parse error when the figure was drawn (after a whole
    evaluation). ``\$`` is a literal dollar, and text without an unescaped ``$`` is never parsed (a backslash
    already before a ``$`` stays shown: ``\\$`` reads as ``\$``).

    Example:
        >>> plain_label("budget $5 to $10")
        'budget \\$5 to \\$10'
    """
    return str(text).replace("$", "\\$")
