r"""The rows of mmetric's model files as text, in blocks: float32 values as C's ``%.9g``, integers in decimal.

mmetric streams its floats at ``max_digits10`` (9) significant digits, which glibc prints as ``%.9g`` of the value
promoted to double. A row is a prefix (``"v "``, ``"3 "``, ``""``) and each value followed by its column's separator
(``" "``, ``"/"``, the row's ``"\n"``). The C++ ``"pcc"`` extension formats them (``native/model_text.cpp``,
``std::to_chars``, 6-8x faster than Python's formatting at 1M points); where it cannot be built, Python's ``%``
formatting gives the same bytes. Both print glibc's ``-nan`` for a NaN whose sign bit is set (Python alone prints
``nan``). The rows come in blocks of :data:`BLOCK_ROWS`, so a file is written without its whole text in memory.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
import torch

from torchmeshmetric import native

__all__ = ["BLOCK_ROWS", "text_rows"]

BLOCK_ROWS = 1 << 16
"""Rows formatted per block: ~2-10 MB of text, a bounded memory whatever the file's size."""


def text_rows(
    floats: np.ndarray | None, ints: np.ndarray | None, *, prefix: str, seps: Sequence[str]
) -> Iterator[bytes]:
    r"""The rows' UTF-8 text in blocks: ``prefix``, then each value and its separator (float columns first).

    Args:
        floats: ``(N, Cf)`` values, taken as float32 and printed as C's ``%.9g`` of them; ``None``: no float column.
        ints: ``(N, Ci)`` integers, printed in decimal; ``None``: no integer column.
        prefix: the text that starts every row.
        seps: the ``Cf + Ci`` texts that follow each column's value (the last one ends the row).

    Yields:
        The text of up to :data:`BLOCK_ROWS` consecutive rows (nothing for ``N = 0``).

    Raises:
        ValueError: ``floats`` and ``ints`` are both ``None``, are not 2-D, have different row counts, or ``seps``
            does not have one text per column.

    Example:
        >>> b"".join(text_rows(np.array([[0.1, -0.0]]), np.array([[7]]), prefix="v ", seps=[" ", " ", "\n"]))
        b'v 0.100000001 -0 7\n'
    """
    if floats is None and ints is None:
        raise ValueError("text_rows: floats and ints are both None, expected at least one column set")
    n = len(floats) if floats is not None else len(ints)  # type: ignore[arg-type]
    # contiguous and writable, as torch.from_numpy takes them (a read-only array is copied)
    f = np.zeros((n, 0), np.float32) if floats is None else np.require(floats, np.float32, ["C", "W"])
    k = np.zeros((n, 0), np.int64) if ints is None else np.require(ints, np.int64, ["C", "W"])
    if f.ndim != 2 or k.ndim != 2:
        raise ValueError(f"text_rows: floats and ints must be 2-D tables, found shapes {f.shape} and {k.shape}")
    if len(f) != len(k):
        raise ValueError(f"text_rows: floats has {len(f)} rows and ints {len(k)}, expected as many")
    if len(seps) != f.shape[1] + k.shape[1]:
        raise ValueError(f"text_rows: seps has {len(seps)} texts, expected one per column ({f.shape[1] + k.shape[1]})")
    ext = native.try_load("pcc")  # None without a C++ compiler: Python's formatting, the same bytes
    for start in range(0, n, BLOCK_ROWS):
        fb, kb = f[start : start + BLOCK_ROWS], k[start : start + BLOCK_ROWS]
        if ext is not None:
            yield ext.format_model_rows(torch.from_numpy(fb), torch.from_numpy(kb), prefix, list(seps))
        else:
            yield _python_rows(fb, kb, prefix, seps).encode("utf-8")


def _python_rows(f: np.ndarray, k: np.ndarray, prefix: str, seps: Sequence[str]) -> str:
    """:func:`text_rows`' block in Python: ``%.9g`` of each float32 value as a double, as C's printf promotes it."""
    kinds = ["%.9g"] * f.shape[1] + ["%d"] * k.shape[1]
    template = prefix.replace("%", "%%") + "".join(c + s.replace("%", "%%") for c, s in zip(kinds, seps, strict=True))
    with np.errstate(invalid="ignore"):  # a signalling NaN is quieted, as C's float-to-double promotion does
        values = f.astype(np.float64).tolist()
    if k.shape[1]:
        values = [a + b for a, b in zip(values, k.tolist(), strict=True)]
    rows = [template % tuple(v) for v in values]
    negative_nan = np.isnan(f) & np.signbit(f)
    for r in np.flatnonzero(negative_nan.any(axis=1)).tolist():  # glibc prints their sign, Python does not
        texts = ["-nan" if negative_nan[r, j] else format(x, ".9g") for j, x in enumerate(values[r][: f.shape[1]])]
        texts += [str(x) for x in values[r][f.shape[1] :]]
        rows[r] = prefix + "".join(t + s for t, s in zip(texts, seps, strict=True))
    return "".join(rows)
