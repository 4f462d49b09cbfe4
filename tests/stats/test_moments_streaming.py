import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric import EmptyInputError
from torchmeshmetric.stats import DistanceAccumulator, Moments, distance_statistics, merge_moments, moments_of

values = st.lists(st.floats(0, 1e3, allow_nan=False, allow_infinity=False), min_size=0, max_size=40)


@settings(max_examples=60, deadline=None)
@given(st.lists(values, min_size=1, max_size=6))
def test_chan_merge_equals_concatenation(parts):
    flat = [x for p in parts for x in p]
    rows = Moments(
        *[torch.stack(f) for f in zip(*[moments_of(torch.tensor(p, dtype=torch.float64)) for p in parts], strict=True)]
    )
    m = merge_moments(rows)
    assert float(m.count) == len(flat)
    if not flat:
        assert float(m.m2) == 0 and float(m.min) == np.inf
        return
    ref = moments_of(torch.tensor(flat, dtype=torch.float64))
    scale = max(1.0, max(flat)) ** 2 * len(flat)
    assert float(m.mean) == pytest.approx(float(ref.mean), rel=1e-12, abs=1e-12 * max(flat))
    assert float(m.m2) == pytest.approx(float(ref.m2), rel=1e-9, abs=1e-12 * scale)
    assert float(m.sumsq) == pytest.approx(float(ref.sumsq), rel=1e-12)
    assert float(m.min) == min(flat) and float(m.max) == max(flat)


def test_pairwise_merge_order_independent_large_offset():
    rng = np.random.default_rng(0)
    chunks = [torch.from_numpy((1e6 + rng.uniform(0, 1, n)).astype(np.float32)) for n in (3, 1000, 1, 57)]
    forward = DistanceAccumulator()
    for c in chunks:
        forward.update(c)
    backward = DistanceAccumulator()
    for c in reversed(chunks):
        backward.update(c)
    flat = torch.cat(chunks).double().numpy()
    for acc in (forward, backward):
        s = acc.compute()
        assert float(s.var) == pytest.approx(np.var(flat), rel=1e-9)
        assert float(s.ave) == pytest.approx(np.mean(flat), rel=1e-14)


@pytest.mark.parametrize("exact", [True, False])
def test_accumulator_batch_by_batch_and_merged_equals_function(exact):
    rng = np.random.default_rng(1)
    batches = [torch.from_numpy(rng.gamma(2, 0.1, n)) for n in (10, 0, 333, 1, 70)]
    a, b = DistanceAccumulator(exact_quantiles=exact), DistanceAccumulator(exact_quantiles=exact)
    for i, x in enumerate(batches):
        (a if i % 2 else b).update(x)
    a.merge(b)
    ref = distance_statistics(torch.cat(batches), peak=2.0, exact_quantiles=exact)
    got = a.compute(peak=2.0)
    for name in ("ave", "var", "std", "mse", "rmse", "max", "min", "count", "psnr"):
        assert float(getattr(got, name)) == pytest.approx(float(getattr(ref, name)), rel=1e-12), name
    for name in ("median", "p95", "p99"):
        assert float(getattr(got, name)) == pytest.approx(float(getattr(ref, name)), rel=1e-12 if exact else 2e-3)


def test_accumulator_empty_and_mismatched_merge():
    acc = DistanceAccumulator()
    acc.update(torch.zeros(0))
    with pytest.raises(EmptyInputError):
        acc.compute()
    with pytest.raises(ValueError, match="quantile mode"):
        acc.merge(DistanceAccumulator(exact_quantiles=False))
