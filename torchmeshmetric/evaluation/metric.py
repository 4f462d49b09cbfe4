"""Deprecated module: :class:`~torchmeshmetric.evaluation.TemporalConsistency` lives in ``temporal_consistency``.

Its name read like the :mod:`torchmeshmetric.metrics` package; import ``TemporalConsistency`` from
:mod:`torchmeshmetric.evaluation` (or :mod:`torchmeshmetric.evaluation.temporal_consistency`) instead.
"""

from __future__ import annotations

import warnings
from typing import Any

from torchmeshmetric.evaluation import temporal_consistency

__all__: list[str] = []


def __getattr__(name: str) -> Any:
    if name != "TemporalConsistency":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    warnings.warn(
        "torchmeshmetric.evaluation.metric is deprecated: import TemporalConsistency from torchmeshmetric.evaluation",
        DeprecationWarning,
        stacklevel=2,
    )
    return temporal_consistency.TemporalConsistency
