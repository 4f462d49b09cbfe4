"""The pcc comparison's C++ paths (merge, search, point-to-plane errors) against its numpy fallback, bit for bit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from torchmeshmetric import native
from torchmeshmetric.mpeg.comparison.pcc import mpeg_compare
from torchmeshmetric.mpeg.core.point_cloud import PointCloud


def _cloud(rng: np.random.Generator, n: int, nan_normals: bool) -> PointCloud:
    pts = (np.round(rng.random((n, 3)) * 40) / 40).astype(np.float32)  # a lattice: duplicates and ties
    nrm = rng.normal(size=(n, 3)).astype(np.float32)
    if nan_normals:
        nrm[::17, 1] = np.nan  # dmetric's fallback for a NaN normal
    col = (rng.random((n, 3)) * 255).astype(np.float32)
    return PointCloud(torch.from_numpy(pts), torch.from_numpy(nrm), torch.from_numpy(col))


@pytest.mark.parametrize("nan_normals", [False, True])
def test_compare_native_equals_numpy(nan_normals: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    if native.try_load("pcc") is None:
        pytest.skip("C++ extension unavailable")
    rng = np.random.default_rng(21)
    ref, dis = _cloud(rng, 20000, nan_normals), _cloud(rng, 15000, False)
    dis = PointCloud(dis.points, None, dis.colors)  # the distorted normals transferred from the reference
    got = mpeg_compare(ref, dis, peak=1.0)
    load = native.try_load
    monkeypatch.setattr(native, "try_load", lambda name: None if name == "pcc" else load(name))
    want = mpeg_compare(ref, dis, peak=1.0)
    assert dataclasses.asdict(got) == dataclasses.asdict(want)
    assert got.points_ref < 20000 and np.isfinite(got.symmetric.d2_mse)
