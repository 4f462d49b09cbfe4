import math

import numpy as np
import pytest
import torch

from torchmeshmetric import EmptyInputError, NonFiniteError, ShapeError
from torchmeshmetric.stats import distance_statistics, linear_quantiles, psnr_from_mse
from torchmeshmetric.stats.statistics import _linear_quantiles


def numpy_reference(d, ddof=0, peak=None):
    d = np.asarray(d, dtype=np.float64)
    mse = np.mean(d**2)
    out = {
        "ave": np.mean(d),
        "var": np.var(d, ddof=ddof),
        "std": np.std(d, ddof=ddof),
        "mse": mse,
        "rmse": np.sqrt(mse),
        "max": np.max(d),
        "min": np.min(d),
        "median": np.percentile(d, 50),
        "p95": np.percentile(d, 95),
        "p99": np.percentile(d, 99),
        "count": d.size,
    }
    if peak is not None:
        out["psnr"] = 10 * np.log10(peak**2 / mse)
    return out


def assert_matches(stats, ref, rtol=1e-12):
    got = stats.as_dict()
    assert set(got) == set(ref)
    for k, v in ref.items():
        assert got[k] == pytest.approx(v, rel=rtol, abs=0), k


@pytest.mark.parametrize("ddof", [0, 1])
@pytest.mark.parametrize("n", [2, 7, 1000])
def test_matches_numpy_random(n, ddof):
    rng = np.random.default_rng(n)
    d = rng.gamma(2.0, 0.01, size=n)
    assert_matches(distance_statistics(torch.from_numpy(d), ddof=ddof, peak=1.7), numpy_reference(d, ddof, 1.7))


def test_real_shaped_float32_data():
    # ~20k distances like a real frame (paper: ~20k vertices), float32, heavy-tailed.
    rng = np.random.default_rng(0)
    d = (np.abs(rng.standard_cauchy(20_000)) * 1e-3).astype(np.float32)
    s = distance_statistics(torch.from_numpy(d), peak=2.0)
    assert_matches(s, numpy_reference(d.astype(np.float64), 0, 2.0), rtol=1e-10)


def test_mse_identity_and_dtype():
    d = torch.rand(500, dtype=torch.float32)
    s = distance_statistics(d)
    assert s.ave.dtype == torch.float64 and s.ave.dim() == 0
    assert float(s.mse) == pytest.approx(float(s.var + s.ave**2), rel=1e-12)
    assert float(s.mse) >= float(s.ave) ** 2


def test_large_offset_float32_no_cancellation():
    # Values near 1e4 with spread 1e-2: E[d^2] - E[d]^2 in float32 would lose everything.
    rng = np.random.default_rng(1)
    d = (1e4 + rng.uniform(0, 1e-2, 10_000)).astype(np.float32)
    s = distance_statistics(torch.from_numpy(d))
    ref = np.var(d.astype(np.float64))
    assert float(s.var) == pytest.approx(ref, rel=1e-9)


def test_single_value_set():
    s = distance_statistics(torch.tensor([0.25]), peak=1.0)
    assert s.as_dict() == pytest.approx(
        {
            "ave": 0.25, "var": 0.0, "std": 0.0, "mse": 0.0625, "rmse": 0.25, "max": 0.25, "min": 0.25,
            "median": 0.25, "p95": 0.25, "p99": 0.25, "count": 1, "psnr": 10 * math.log10(16),
        }
    )  # fmt: skip
    s1 = distance_statistics(torch.tensor([0.25]), ddof=1)
    assert math.isnan(float(s1.var)) and math.isnan(float(s1.std))


def test_psnr_rules():
    s = distance_statistics(torch.zeros(4), peak=2.0)
    assert float(s.psnr) == math.inf
    assert distance_statistics(torch.ones(3)).psnr is None
    assert "psnr" not in distance_statistics(torch.ones(3)).as_dict()
    assert float(psnr_from_mse(torch.tensor(0.25, dtype=torch.float64), 1.0)) == pytest.approx(10 * math.log10(4))


def test_ragged_batch_list_and_packed_agree_with_per_item():
    rng = np.random.default_rng(2)
    items = [rng.uniform(0, 1, n) for n in (5, 1, 300, 17)]
    s_list = distance_statistics([torch.from_numpy(x) for x in items], peak=3.0)
    packed = torch.from_numpy(np.concatenate(items))
    s_packed = distance_statistics(packed, lengths=torch.tensor([len(x) for x in items]), peak=3.0)
    assert s_list.ave.shape == (4,)
    for b, (x, one) in enumerate(zip(items, s_list.unbind(), strict=True)):
        assert_matches(one, numpy_reference(x, 0, 3.0))
        assert float(s_packed.p99[b]) == pytest.approx(np.percentile(x, 99), rel=1e-12)


def test_ragged_batch_empty_item_is_nan_with_zero_count():
    s = distance_statistics([torch.tensor([1.0, 2.0]), torch.zeros(0)])
    assert s.count.tolist() == [2, 0]
    assert math.isnan(float(s.ave[1])) and math.isnan(float(s.median[1]))
    assert float(s.ave[0]) == 1.5


def test_errors():
    with pytest.raises(EmptyInputError, match="dists"):
        distance_statistics(torch.zeros(0))
    with pytest.raises(NonFiniteError, match="dists"):
        distance_statistics(torch.tensor([1.0, float("nan")]))
    with pytest.raises(ShapeError, match="dists"):
        distance_statistics(torch.zeros(3, 2))
    with pytest.raises(ShapeError, match="lengths"):
        distance_statistics(torch.zeros(3), lengths=torch.tensor([1, 1]))
    with pytest.raises(ValueError, match="ddof"):
        distance_statistics(torch.ones(3), ddof=-1)
    with pytest.raises(ValueError, match="as_dict"):
        distance_statistics([torch.ones(2), torch.ones(3)]).as_dict()


def test_linear_quantiles_matches_numpy_edges():
    rng = np.random.default_rng(3)
    x = rng.normal(size=101)
    q = [0.0, 0.01, 0.5, 0.95, 0.99, 1.0]
    got = linear_quantiles(torch.from_numpy(x), q).numpy()
    np.testing.assert_allclose(got, np.percentile(x, np.array(q) * 100), rtol=1e-13, atol=0)


def test_approximate_quantiles_within_bound():
    rng = np.random.default_rng(4)
    d = rng.lognormal(-3, 1.5, 5000)
    s = distance_statistics(torch.from_numpy(d), exact_quantiles=False, relative_accuracy=0.01)
    for name, q in (("median", 50), ("p95", 95), ("p99", 99)):
        exact = np.percentile(d, q)
        assert abs(float(getattr(s, name)) - exact) <= 0.01 * exact * (1 + 1e-9), name
    assert float(s.ave) == pytest.approx(np.mean(d), rel=1e-12)  # moments stay exact


def _two_pass_quantiles(x: torch.Tensor, q: list[float], lens: torch.Tensor) -> torch.Tensor:
    """The quantiles as linear_quantiles formed them before its numpy sort: two stable torch sorts (the oracle)."""
    from torchmeshmetric.structures import batch_index, lengths_to_offsets

    b = batch_index(lens)
    order = torch.argsort(x, stable=True)
    xs = x[order[torch.argsort(b[order], stable=True)]]
    off, n = lengths_to_offsets(lens)[:-1], lens.to(torch.float64)
    pos = torch.tensor(q, dtype=torch.float64)[None, :] * (n[:, None] - 1).clamp_min(0)
    lo, hi = torch.floor(pos), torch.ceil(pos)
    last = max(x.numel() - 1, 0)
    lo_v, hi_v = xs[(off[:, None] + lo.long()).clamp(max=last)], xs[(off[:, None] + hi.long()).clamp(max=last)]
    out = lo_v + (pos - lo) * (hi_v - lo_v)
    return torch.where((lens > 0)[:, None], out, torch.full_like(out, float("nan")))


@pytest.mark.parametrize("seed", range(6))
def test_linear_quantiles_bit_identical_to_the_two_stable_torch_sorts(seed: int) -> None:
    """The per-item numpy sort (docs/benchmarks.md, eleventh round) gives the quantiles' bits of the stable torch
    sorts it replaced: ties, zeros of both signs (whose order an unstable sort may swap), infinities, empty items.
    The unchecked form the statistics call: the public one refuses infinities (review V, F5)."""

    rng = np.random.default_rng(seed)
    sizes = [int(n) for n in rng.integers(0, 40, size=int(rng.integers(1, 7)))] + [0, 1, 2]
    rng.shuffle(sizes)
    pool = np.array([0.0, -0.0, 1.5, 1.5, 2.0**-1074, -(2.0**-1074), np.inf, -np.inf, 3.0, -3.0])
    x = np.where(rng.random(sum(sizes)) < 0.5, rng.choice(pool, sum(sizes)), rng.normal(size=sum(sizes)))
    lens = torch.tensor(sizes)
    q = [0.0, 0.01, 0.25, 0.5, 0.95, 0.99, 1.0]
    got = _linear_quantiles(torch.from_numpy(x), q, lens)
    want = _two_pass_quantiles(torch.from_numpy(x), q, lens)
    assert torch.equal(got.view(torch.int64), want.view(torch.int64))
    one = torch.from_numpy(x[: max(sizes[0], 1)])  # a single item (no lengths)
    want_one = _two_pass_quantiles(one, q, torch.tensor([len(one)]))[0]
    assert torch.equal(_linear_quantiles(one, q).view(torch.int64), want_one.view(torch.int64))


@pytest.mark.parametrize(("num_items", "size"), [(50, 3), (5, 2), (4, 1), (3, 25)])
def test_linear_quantiles_items_of_one_size_bit_identical(num_items: int, size: int) -> None:
    """Items of one size are sorted in one call along rows: the bits of the two stable torch sorts all the same."""
    rng = np.random.default_rng(size)
    pool = np.array([0.0, -0.0, 1.5, 2.0**-1074, -(2.0**-1074), np.inf, -np.inf, -3.0])
    x = torch.from_numpy(rng.choice(pool, num_items * size))
    lens, q = torch.full((num_items,), size), [0.0, 0.25, 0.5, 0.95, 1.0]
    assert torch.equal(
        _linear_quantiles(x, q, lens).view(torch.int64), _two_pass_quantiles(x, q, lens).view(torch.int64)
    )


def test_linear_quantiles_many_tiny_items_not_sorted_one_by_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """100k items of 2 values: no numpy sort call per item (a loop of 100k calls made it 3x slower than the two
    torch sorts, 0.242 s against 0.083 s, review W); one call for items of one size, none for tiny items of several."""
    calls = []
    real = np.sort
    monkeypatch.setattr(np, "sort", lambda *a, **k: calls.append(1) or real(*a, **k))
    x = torch.rand(200_001, dtype=torch.float64)
    lens = torch.full((100_000,), 2)
    linear_quantiles(x[:-1], [0.5], lens)
    assert len(calls) == 1
    lens[0] = 3
    linear_quantiles(x, [0.5], lens)
    assert len(calls) == 1
