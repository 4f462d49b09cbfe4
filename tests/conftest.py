"""Shared fixtures: devices and dtypes (CUDA cases skip without a GPU)."""

from __future__ import annotations

import pytest
import torch

CUDA = [pytest.mark.cuda, pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA")]
"""Marks of a test (or parameter) that needs a CUDA device: selected by ``pytest -m cuda``, skipped without one."""

DEVICES = ["cpu", pytest.param("cuda", marks=CUDA)]


@pytest.fixture(params=DEVICES)
def device(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture(params=[torch.float32, torch.float64], ids=["f32", "f64"])
def dtype(request: pytest.FixtureRequest) -> torch.dtype:
    return request.param  # type: ignore[no-any-return]
