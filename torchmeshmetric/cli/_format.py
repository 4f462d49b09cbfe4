"""Text in and out of the commands, without torch: JSON-safe values, figures as text, box corners from text.

Imported by parsers and by commands that must start fast (``bdrate`` computes without torch).
"""

from __future__ import annotations

import math
import re
from typing import Any

__all__ = ["corner", "fmt_figure", "json_safe"]


def json_safe(value: Any) -> Any:
    """Replace non-finite floats by the strings ``"inf"``, ``"-inf"``, ``"nan"`` (strict JSON has no infinity).

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


def fmt_figure(x: Any, small: bool = False) -> str:
    """A figure as the tables print it: 4 decimals, ``inf``/``nan``; with ``small``, 6 significant digits below 1e-3.

    Example:
        >>> fmt_figure(42.123456), fmt_figure(float("inf")), fmt_figure(1.5e-5, small=True), fmt_figure(3)
        ('42.1235', 'inf', '1.5e-05', '3')
    """
    if isinstance(x, float):
        if math.isinf(x) or math.isnan(x):
            return "inf" if x > 0 else ("-inf" if x < 0 else "nan")
        return f"{x:.6g}" if small and abs(x) < 1e-3 else f"{x:.4f}"
    return str(x)


def corner(text: str, option: str) -> list[float]:
    """A box corner given as three finite numbers (``"-1 -1 -1"`` or ``"-1,-1,-1"``).

    Args:
        text: the option's value.
        option: the option's name in the error (``"--min-pos"``).

    Raises:
        ValueError: not three finite numbers.

    Example:
        >>> corner("-1, 0 2.5", "--min-pos")
        [-1.0, 0.0, 2.5]
    """
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f'{option}: expected three finite numbers such as "-1 -1 -1", found {text!r}')
    return values
