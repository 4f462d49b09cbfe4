"""Deprecated module: :class:`~torchmeshmetric.evaluation.TemporalConsistency` lives in ``temporal_consistency``.

Its name read like the :mod:`torchmeshmetric.metrics` package; import ``TemporalConsistency`` from
:mod:`torchmeshmetric.evaluation` instead.
"""

from torchmeshmetric._deprecation import deprecated_names
from torchmeshmetric.evaluation.temporal_consistency import TemporalConsistency as _TemporalConsistency

__all__: list[str] = []

__getattr__ = deprecated_names(
    __name__, {"TemporalConsistency": ("torchmeshmetric.evaluation.TemporalConsistency", _TemporalConsistency)}
)
