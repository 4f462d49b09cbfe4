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
