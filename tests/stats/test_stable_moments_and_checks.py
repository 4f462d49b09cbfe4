"""Review D, findings 6-8 and 13: sketch input on the batched path, peak/ddof checks, stable and exact moments."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch

from torchmeshmetric.stats import DistanceAccumulator, SketchRangeWarning
from torchmeshmetric.stats.statistics import distance_statistics


@pytest.mark.parametrize("batched", [False, True])
def test_the_sketch_refuses_negative_distances_on_every_path(batched):
    # The lengths= path skipped the check and returned a median of 0.4995 (exact: 0).
    kw = {"lengths": torch.tensor([2])} if batched else {}
    with pytest.raises(ValueError, match=r"dists: the quantile sketch takes distances >= 0, found -1.0"):
        distance_statistics(torch.tensor([-1.0, 1.0]), exact_quantiles=False, **kw)
    with pytest.raises(ValueError, match=r"dists: the quantile sketch takes distances >= 0, found -1.0"):
        distance_statistics([torch.tensor([-1.0, 1.0])], exact_quantiles=False)


@pytest.mark.parametrize("peak", [0.0, -1.0, float("nan"), float("inf")])
def test_a_peak_that_is_not_finite_and_positive_is_refused(peak):
    # 0 gave psnr -inf, -1 the psnr of +1, NaN a NaN psnr.
    with pytest.raises(ValueError, match=r"peak: expected a finite number > 0, found"):
        distance_statistics(torch.tensor([1.0, 2.0]), peak=peak)
    with pytest.raises(ValueError, match=r"peak: expected a finite number > 0, found"):
        acc = DistanceAccumulator()
        acc.update(torch.tensor([1.0]))
        acc.compute(peak=peak)


def test_a_peak_tensor_is_checked_too():
    with pytest.raises(ValueError, match=r"peak: expected positive values, found 0.0"):
        distance_statistics([torch.tensor([1.0]), torch.tensor([2.0])], peak=torch.tensor([1.0, 0.0]))
    with pytest.raises(ValueError, match=r"peak"):
        distance_statistics(torch.tensor([1.0, 2.0]), peak=torch.tensor(float("nan")))
    assert float(distance_statistics(torch.tensor([0.1]), peak=torch.tensor(1.0)).psnr) == pytest.approx(20.0)


@pytest.mark.parametrize(("ddof", "error"), [(1.5, TypeError), (True, TypeError), (-1, ValueError)])
def test_ddof_must_be_a_non_negative_int(ddof, error):
    # 1.5 gave a variance divided by n - 1.5.
    with pytest.raises(error, match=r"ddof: expected an int"):
        distance_statistics(torch.tensor([1.0, 2.0, 4.0]), ddof=ddof)


def test_an_integral_float_ddof_is_taken_as_before():
    # ddof=1.0 worked before ddof was checked (found by review of the check): it is 1, as numpy takes it.
    x = torch.tensor([1.0, 2.0, 4.0], dtype=torch.float64)
    assert torch.equal(distance_statistics(x, ddof=1.0).var, distance_statistics(x, ddof=1).var)


def test_a_constant_set_has_its_value_as_mean_and_variance_exactly_0_however_it_is_batched():
    # Was: one-shot std 8.7e-11, and 2.4e-8 off the mean streamed one value per update.
    x = torch.full((20000,), 123456.789, dtype=torch.float64)
    for stats in [distance_statistics(x), distance_statistics(x, lengths=torch.tensor([5000, 15000]))]:
        assert torch.all(stats.ave == 123456.789) and torch.all(stats.var == 0)
    for batch in (1, 7, 1000):
        acc = DistanceAccumulator()
        for v in x.split(batch):
            acc.update(v)
        s = acc.compute()
        assert float(s.ave) == 123456.789 and float(s.var) == 0.0


def test_streamed_moments_do_not_drift_with_the_number_of_updates():
    # Uniform data in [0, 10), 20 000 values: the relative error of the streamed ave was 2e-13 (batches of 1),
    # 2e-14 (10), 1e-16 (1000); measured now, against numpy in float64: ave 8.8e-16 / 1.6e-15 / 1.8e-16, var
    # 6.0e-15 / 2.3e-15 / 4.3e-16 (about sqrt(updates) roundings). Asserted: 1e-14 for both.
    u = torch.rand(20000, dtype=torch.float64, generator=torch.Generator().manual_seed(0)) * 10
    mean, var = np.mean(u.numpy()), np.var(u.numpy())
    for batch in (1, 10, 1000):
        acc = DistanceAccumulator()
        for v in u.split(batch):
            acc.update(v)
        s = acc.compute()
        assert abs(float(s.ave) - mean) <= 1e-14 * mean
        assert abs(float(s.var) - var) <= 1e-14 * var


def test_values_near_the_float64_maximum_give_finite_mean_and_variance():
    # ave and var were inf for [1.7e308, 1.7e308] (the sum overflowed); streaming a constant 1e300 gave var inf.
    s = distance_statistics(torch.tensor([1.7e308, 1.7e308], dtype=torch.float64))
    assert float(s.ave) == 1.7e308 and float(s.var) == 0.0
    s = distance_statistics(torch.tensor([1.7e308, 1.0e308, 1.5e308], dtype=torch.float64))
    assert float(s.ave) == pytest.approx(1.4e308, rel=1e-15)
    assert float(s.var) == float("inf")  # its true value, 8.7e614, is beyond float64
    b = distance_statistics(torch.tensor([1.7e308, 1.7e308, 1.0], dtype=torch.float64), lengths=torch.tensor([2, 0, 1]))
    assert b.ave[0] == 1.7e308 and b.var[0] == 0 and b.ave[2] == 1.0 and torch.isnan(b.ave[1])
    acc = DistanceAccumulator()
    for _ in range(10):
        acc.update(torch.tensor([1e300], dtype=torch.float64))
    assert float(acc.compute().ave) == 1e300 and float(acc.compute().var) == 0.0


@pytest.mark.parametrize("exact", [True, False])
def test_rmse_std_and_psnr_stay_finite_where_mse_and_var_overflow(exact):
    # mse = mean(d^2) of distances near 1e200 is past float64 (inf, its true value's overflow) and so is var for a
    # spread of 2e200; rmse and std were sqrt(inf) = inf and the PSNR -inf (NaN with a peak above 1e154), though
    # rmse <= max|d| and std are representable.
    s = distance_statistics(torch.tensor([1e200, 3e200], dtype=torch.float64), peak=1e200, exact_quantiles=exact)
    assert float(s.mse) == float("inf") and float(s.var) == float("inf")
    assert float(s.rmse) == pytest.approx(5**0.5 * 1e200, rel=1e-15)
    assert float(s.std) == pytest.approx(1e200, rel=1e-15)
    assert float(s.psnr) == pytest.approx(-10 * np.log10(5.0), rel=1e-12)  # 20 log10(1e200 / (sqrt(5) 1e200))
    s = distance_statistics(torch.tensor([1.7e308, 1.7e308], dtype=torch.float64), peak=1.7e308)
    assert float(s.rmse) == 1.7e308 and float(s.psnr) == 0.0 and float(s.std) == 0.0


def test_overflowed_roots_on_every_path():
    # A batch: the big item's rmse/std from its scaled values; the small item's figures are the plain ones. (One
    # scale for the whole batch underflowed the small item's deviations: its var came out 0/0 = NaN.)
    d = torch.tensor([1e200, 3e200, 1.0, 2.0, 5.0], dtype=torch.float64)
    b = distance_statistics(d, lengths=torch.tensor([2, 0, 2, 1]), ddof=1, peak=10.0)
    assert float(b.std[0]) == pytest.approx(2**0.5 * 1e200, rel=1e-15)
    assert float(b.rmse[0]) == pytest.approx(5**0.5 * 1e200, rel=1e-15)
    assert float(b.var[2]) == 0.5 and float(b.rmse[2]) == 2.5**0.5 and torch.isnan(b.var[3])
    assert float(b.psnr[3]) == pytest.approx(20 * np.log10(2.0), rel=1e-14)
    # Streaming: a constant 1e300, one value per update, in both quantile modes (the sketch keeps no values: its
    # rmse is sqrt(var + ave^2) from the moments), and a spread of 2e200 with exact quantiles.
    for exact in (True, False):
        acc = DistanceAccumulator(exact_quantiles=exact)
        for _ in range(10):
            acc.update(torch.tensor([1e300], dtype=torch.float64))
        # The sketch's fixed window ends at 1e12: its quantiles of 1e300 say so (review V, F4).
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            s = acc.compute(peak=1e300)
        assert [w.category for w in caught] == ([] if exact else [SketchRangeWarning])
        assert (float(s.var), float(s.rmse), float(s.psnr)) == (0.0, 1e300, 0.0)
    acc = DistanceAccumulator()
    for v in (1e200, 3e200):
        acc.update(torch.tensor([v], dtype=torch.float64))
    s = acc.compute()
    assert float(s.std) == pytest.approx(1e200, rel=1e-15) and float(s.rmse) == pytest.approx(5**0.5 * 1e200, rel=1e-15)


def test_psnr_where_the_peak_squared_or_the_quotient_leaves_float64():
    # peak**2 overflowed (1e200: PSNR inf for an mse of 1), the quotient overflowed (1e20 / 1e-300), and a subnormal
    # mse was clamped to 2.2e-308 (3076.5 dB instead of 3200).
    from torchmeshmetric.stats.statistics import psnr_from_mse

    mse = torch.tensor([1.0, 1e-300, 1e-320, 4.0], dtype=torch.float64)
    got = psnr_from_mse(mse, 1e10).tolist()
    assert got[0] == 200.0 and got[3] == pytest.approx(200 - 10 * np.log10(4.0), rel=1e-15)
    assert got[1] == pytest.approx(3200.0, rel=1e-15) and got[2] == pytest.approx(
        200 - 10 * np.log10(1e-320), rel=1e-15
    )
    assert float(psnr_from_mse(torch.tensor(1.0, dtype=torch.float64), 1e200)) == pytest.approx(4000.0, rel=1e-15)


def test_symmetric_rmse_and_psnr_where_the_mse_overflows():
    # symmetric_rmse was sqrt(max(mse, reverse_mse)) = inf; a peak of 1e200 given as a Python float was made float32
    # (inf) and refused as "expected finite values > 0".
    from torchmeshmetric.metrics import DistanceStatisticsMetric

    m = DistanceStatisticsMetric(two_sided=True, peak=1e200)
    m.update(torch.tensor([1e200, 3e200], dtype=torch.float64), torch.tensor([1.0, 2.0], dtype=torch.float64))
    out = m.compute()
    assert float(out["symmetric_mse"]) == float("inf")
    assert float(out["symmetric_rmse"]) == float(out["rmse"]) == pytest.approx(5**0.5 * 1e200, rel=1e-15)
    assert float(out["symmetric_psnr"]) == float(out["psnr"]) == pytest.approx(-10 * np.log10(5.0), rel=1e-12)
    assert float(out["reverse_psnr"]) == pytest.approx(4000 - 10 * np.log10(2.5), rel=1e-15)
