import numpy as np
import pytest
import torch

from torchmeshmetric.stats import QuantileSketch


@pytest.mark.parametrize("alpha", [1e-3, 1e-2, 0.05])
def test_relative_error_bound_on_every_order_statistic(alpha):
    rng = np.random.default_rng(0)
    x = np.sort(np.concatenate([rng.lognormal(0, 3, 2000), rng.uniform(1e-9, 1e-8, 50), [1e9]]))
    sk = QuantileSketch(alpha)
    counts = sk.counts(torch.from_numpy(x))
    q = torch.linspace(0, 1, 401, dtype=torch.float64)
    est = sk.quantile(counts, q, torch.tensor(x.min()), torch.tensor(x.max())).numpy()
    exact = np.percentile(x, q.numpy() * 100)
    rel = np.abs(est - exact) / exact
    assert rel.max() <= alpha * (1 + 1e-9)


def test_zero_bucket_and_merge_by_addition():
    sk = QuantileSketch(0.01, min_value=1e-6)
    a = torch.tensor([0.0, 0.0, 5e-7, 1.0])
    b = torch.tensor([2.0, 3.0])
    merged = sk.counts(a) + sk.counts(b)
    assert torch.equal(merged, sk.counts(torch.cat([a, b])))
    assert int(merged[0]) == 3  # values below min_value share the zero bucket
    med = sk.quantile(merged, torch.tensor([0.0]), torch.tensor(0.0), torch.tensor(3.0))
    assert float(med) == 0.0
    assert torch.isnan(
        sk.quantile(torch.zeros(sk.num_bins), torch.tensor([0.5]), torch.tensor(0.0), torch.tensor(1.0))
    ).all()


def test_bad_arguments():
    with pytest.raises(ValueError, match="relative_accuracy"):
        QuantileSketch(0.0)
    with pytest.raises(ValueError, match="min_value"):
        QuantileSketch(0.01, min_value=1.0, max_value=0.5)


_SCALES = [1e13, 1e-13, 1e-300, 1e300, 1e-320]


@pytest.mark.parametrize("scale", _SCALES)
def test_one_shot_sketched_quantiles_keep_their_relative_error_at_any_scale(scale):
    # Review V, F4: the sketch's window was fixed at [1e-12, 1e12]: distances around 1e13 got median = 1e12 (true
    # 4.8e12), around 1e-13 the minimum. The one-shot statistics have all values at hand: the window follows them.
    from torchmeshmetric import distance_statistics

    d = torch.rand(101, dtype=torch.float64, generator=torch.Generator().manual_seed(0)) * scale
    d = d[d > 0]  # 1e-320: a few round to 0
    exact = distance_statistics(d)
    for got in (
        distance_statistics(d, exact_quantiles=False),
        distance_statistics([d, d / scale], exact_quantiles=False),
        distance_statistics(torch.cat([d, d / scale]), lengths=torch.tensor([len(d), len(d)]), exact_quantiles=False),
    ):
        for field in ("median", "p95", "p99"):
            est, ref = getattr(got, field).reshape(-1)[0], getattr(exact, field)
            # The bound holds for values the dtype represents with relative accuracy (1e-320 is subnormal: its
            # values carry ~10 bits, the counted ones are exact but the bound is relative to the rounded data).
            assert abs(float(est) - float(ref)) <= 1e-3 * float(ref) * (1 + 1e-9), (field, float(est), float(ref))


def test_one_shot_sketched_quantiles_of_ordinary_sets_are_unchanged():
    # Inside the window (maximum <= 1e12, mean >= 1e-6) the counts are those of the fixed window, bit for bit.
    from torchmeshmetric import distance_statistics
    from torchmeshmetric.stats import QUANTILE_LEVELS

    sk = QuantileSketch()
    q = torch.tensor(QUANTILE_LEVELS, dtype=torch.float64)
    for scale in (1e-5, 1.0, 1e6, 1e11):
        d = torch.rand(1000, dtype=torch.float64, generator=torch.Generator().manual_seed(1)) * scale
        fixed = sk.quantile(sk.counts(d), q, d.min(), d.max())
        got = distance_statistics(d, exact_quantiles=False)
        assert torch.equal(torch.stack([got.median, got.p95, got.p99]), fixed)


@pytest.mark.parametrize("scale", [1e13, 1e-13])
def test_streaming_sketched_quantiles_outside_the_window_warn(scale):
    from torchmeshmetric import DistanceStatisticsMetric
    from torchmeshmetric.stats import DistanceAccumulator, SketchRangeWarning

    d = torch.rand(101, dtype=torch.float64, generator=torch.Generator().manual_seed(0)) * scale
    with pytest.warns(SketchRangeWarning, match="relative error"):
        DistanceAccumulator(exact_quantiles=False).update(d).compute()
    metric = DistanceStatisticsMetric(exact_quantiles=False)
    metric.update(d)
    with pytest.warns(SketchRangeWarning, match="min_value|max_value"):
        metric.compute()


def test_streaming_sketched_quantiles_inside_the_window_do_not_warn():
    import warnings

    from torchmeshmetric.stats import DistanceAccumulator, SketchRangeWarning

    d = torch.rand(101, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", SketchRangeWarning)
        DistanceAccumulator(exact_quantiles=False).update(d).update(torch.zeros(5, dtype=torch.float64)).compute()
