"""The names of ``torchmeshmetric.stats``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import moments as moments
from . import sketch as sketch
from . import statistics as statistics
from . import streaming as streaming
from .moments import Moments, merge_moments, moments_of
from .sketch import QuantileSketch, SketchRangeWarning
from .statistics import (
    QUANTILE_LEVELS,
    DistanceStatistics,
    distance_statistics,
    linear_quantiles,
    psnr_from_mse,
    statistics_from_parts,
)
from .streaming import DistanceAccumulator

__all__ = [
    "QUANTILE_LEVELS",
    "DistanceAccumulator",
    "DistanceStatistics",
    "Moments",
    "QuantileSketch",
    "SketchRangeWarning",
    "distance_statistics",
    "linear_quantiles",
    "merge_moments",
    "moments_of",
    "psnr_from_mse",
    "statistics_from_parts",
]
