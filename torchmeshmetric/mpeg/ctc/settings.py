"""The CTC chain's settings: one frozen record of what ``mm sequence`` is told for a sequence and condition.

:func:`~torchmeshmetric.mpeg.ctc.chain.ctc_frame`, :func:`~torchmeshmetric.mpeg.ctc.chain.ctc_sequence`,
:func:`~torchmeshmetric.mpeg.ctc.face_errors.ctc_face_errors`, the campaign runner and the ``ctc`` command all take
the chain's settings as one :class:`CtcSettings`; the functions still accept the settings as separate keywords, which
:func:`resolve_settings` turns into one record (the only place that does).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import MISSING, dataclass, fields
from typing import Any, TypedDict, Union

import numpy as np
from torch import Tensor

from torchmeshmetric.mpeg.ctc.box import check_box
from torchmeshmetric.mpeg.ctc.dequantize import _bits, _corner

__all__ = ["Corner", "CtcKeywords", "CtcSettings", "box_longest_side", "resolve_settings"]

Corner = Union[Sequence[float], np.ndarray, Tensor]  # noqa: UP007 (a runtime alias)

_REQUIRED = ("qp", "qt", "min_pos", "max_pos")


@dataclass(frozen=True)
class CtcSettings:
    """The settings of the CTC chain for one sequence and condition (mmetric's options in brackets).

    Attributes:
        qp: geometry bit depth of the source and decoded frames (``dequantize --qp``).
        qt: UV bit depth of the source (``--qt``).
        min_pos: ``(3,)`` the sequence box's min corner (``--minPos``).
        max_pos: ``(3,)`` its max corner (``--maxPos``).
        resolution: PSNR peak (``compare --resolution``); ``None``: the box's longest side, as the test model does.
        decoded_qt: UV bit depth of the decoded frames (the test model: 0).
        grid_size: ``sample --gridSize`` (1024).
        ibsm_resolution: IBSM's buffer side (``--ibsmResolution``, 2048); ``None`` leaves IBSM out.
        ibsm_cameras: IBSM's camera count (``--ibsmCameraCount``, 16).

    Raises:
        TypeError: a ``resolution`` that is not a real number.
        ValueError: a ``resolution`` that is not positive and finite; a bit depth (``qp``, ``qt``, ``decoded_qt``)
            outside 0..31; a corner that is not 3 finite numbers, or ``max_pos`` below ``min_pos``; ``grid_size``
            below 2, ``ibsm_resolution`` below 1 or ``ibsm_cameras`` below 2 (or not integers). Each names the field.

    Example:
        >>> s = CtcSettings(qp=10, qt=12, min_pos=[-1, -1, -1], max_pos=[1, 1, 3])
        >>> s.peak, s.grid_size, s.ibsm_resolution
        (4.0, 1024, 2048)
    """

    qp: int
    qt: int
    min_pos: Corner
    max_pos: Corner
    resolution: float | None = None
    decoded_qt: int = 0
    grid_size: int = 1024
    ibsm_resolution: int | None = 2048
    ibsm_cameras: int = 16

    def __post_init__(self) -> None:
        """Check every field here, where the caller named it, not deep in the chain under another name."""
        for name in ("qp", "qt", "decoded_qt"):
            _bits(getattr(self, name), name)
        lo, hi = _corner(self.min_pos, "min_pos", 3), _corner(self.max_pos, "max_pos", 3)
        check_box(lo.tolist(), hi.tolist())  # the ctc command's and the manifest's check
        _at_least(self.grid_size, "grid_size", 2)
        if self.ibsm_resolution is not None:
            _at_least(self.ibsm_resolution, "ibsm_resolution", 1, "(or None: no IBSM)")
        _at_least(self.ibsm_cameras, "ibsm_cameras", 2, "(mmetric's Fibonacci sphere)")
        r = self.resolution
        if r is None:
            return
        if isinstance(r, bool) or not isinstance(r, (int, float, np.integer, np.floating)):
            raise TypeError(f"resolution: expected a real number, found {type(r).__name__}")
        if not (math.isfinite(r) and r > 0):
            raise ValueError(f"resolution: expected a positive finite PSNR peak (the box's longest side), found {r}")

    @property
    def box(self) -> tuple[Corner, Corner]:
        """``(min_pos, max_pos)``."""
        return (self.min_pos, self.max_pos)

    @property
    def peak(self) -> float:
        """The PSNR peak: ``resolution``, or the box's longest side when it is ``None``."""
        if self.resolution is not None:
            return self.resolution
        return box_longest_side(self.min_pos, self.max_pos)


class CtcKeywords(TypedDict, total=False):
    """The fields of :class:`CtcSettings` as separate keywords (``**keywords: Unpack[CtcKeywords]``), all optional."""

    qp: int
    qt: int
    min_pos: Corner
    max_pos: Corner
    resolution: float | None
    decoded_qt: int
    grid_size: int
    ibsm_resolution: int | None
    ibsm_cameras: int


def _at_least(value: Any, name: str, low: int, note: str = "") -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name}: expected an integer >= {low}{' ' + note if note else ''}, found {value!r}")


def box_longest_side(min_pos: Corner, max_pos: Corner) -> float:
    """The longest side of the box ``min_pos..max_pos`` (the test model's PSNR peak).

    Example:
        >>> box_longest_side([0, 0, 0], [1, 2, 0.5])
        2.0
    """
    return float(max(float(h) - float(lo) for lo, h in zip(min_pos, max_pos, strict=True)))


def _is_default(name: str, value: Any) -> bool:
    default = _DEFAULTS[name]
    return value is None if default is None else (value is not None and value == default)


def resolve_settings(settings: CtcSettings | None, **keywords: Any) -> CtcSettings:
    """``settings``, or a :class:`CtcSettings` built from the functions' separate keywords.

    A keyword at its field's default (``None`` for ``qp``, ``qt``, ``min_pos``, ``max_pos``, ``resolution``) counts as
    not given, so that ``ibsm_resolution=None`` (no IBSM) is a setting and ``ibsm_resolution=2048`` is the default.

    Args:
        settings: the chain's settings, or ``None`` to build them from ``keywords``.
        **keywords: the functions' separate keywords (``qp``, ``qt``, ``min_pos``, ``max_pos``, ...).

    Raises:
        TypeError: ``settings`` is not a :class:`CtcSettings`; both ``settings`` and a keyword are given; without
            ``settings``, a required keyword (``qp``, ``qt``, ``min_pos``, ``max_pos``) is missing.

    Example:
        >>> s = resolve_settings(None, qp=10, qt=0, min_pos=[0] * 3, max_pos=[1] * 3, ibsm_resolution=None)
        >>> s.grid_size, s.ibsm_resolution
        (1024, None)
    """
    given = {k: v for k, v in keywords.items() if not _is_default(k, v)}
    if settings is not None:
        if not isinstance(settings, CtcSettings):
            raise TypeError(f"settings: expected a CtcSettings, found {type(settings).__name__}")
        if given:
            name = next(iter(given))
            raise TypeError(f"{name}: give the chain's settings either as settings= or as keywords, not both")
        return settings
    for name in _REQUIRED:
        if name not in given:
            raise TypeError(f"{name}: required (or pass settings=CtcSettings(...))")
    return CtcSettings(**given)


_DEFAULTS = {f.name: (None if f.default is MISSING else f.default) for f in fields(CtcSettings)}
