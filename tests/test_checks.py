"""The shared input checks: the fast finiteness test agrees with the elementwise one."""

from __future__ import annotations

import pytest
import torch

from torchmeshmetric._checks import NonFiniteError, all_finite, check_finite


@pytest.mark.parametrize("dtype", [torch.float16, torch.float32, torch.float64])
def test_all_finite_agrees_with_isfinite(dtype: torch.dtype) -> None:
    big = torch.finfo(dtype).max
    cases = [
        torch.tensor([1.0, -2.0, 0.0]),
        torch.tensor([big, big, big]),  # finite values whose sum overflows: still finite
        torch.tensor([-big, -big]),
        torch.tensor([1.0, float("nan")]),
        torch.tensor([float("inf"), 1.0]),
        torch.tensor([float("inf"), -float("inf")]),  # the sum is NaN
        torch.tensor([-float("inf")]),
    ]
    for x in cases:
        x = x.to(dtype)
        assert all_finite(x) == bool(torch.isfinite(x).all()), x


def test_all_finite_does_not_record_gradients() -> None:
    x = torch.ones(4, 3, requires_grad=True)
    assert all_finite(x)
    assert x.grad is None


def test_check_finite_counts_the_bad_values() -> None:
    x = torch.tensor([[1.0, float("nan"), float("inf")], [3e38, 3e38, 3e38]])
    with pytest.raises(NonFiniteError, match="points: expected finite values, found 2 NaN/Inf"):
        check_finite(x, "points")
    check_finite(x[1:], "points")  # an overflowing sum of finite values is accepted
