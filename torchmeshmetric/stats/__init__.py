"""Statistics of distance sets: the paper's five (Ave, Var, STD, MSE, RMSE) plus Hausdorff, quantiles and PSNR."""

from torchmeshmetric.stats.moments import Moments, merge_moments, moments_of
from torchmeshmetric.stats.sketch import QuantileSketch
from torchmeshmetric.stats.statistics import (
    QUANTILE_LEVELS,
    DistanceStatistics,
    distance_statistics,
    linear_quantiles,
    psnr_from_mse,
    statistics_from_parts,
)
from torchmeshmetric.stats.streaming import DistanceAccumulator

__all__ = [
    "QUANTILE_LEVELS",
    "DistanceAccumulator",
    "DistanceStatistics",
    "Moments",
    "QuantileSketch",
    "distance_statistics",
    "linear_quantiles",
    "merge_moments",
    "moments_of",
    "psnr_from_mse",
    "statistics_from_parts",
]
