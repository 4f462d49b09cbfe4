"""unique_vertex_rows: the hashed duplicate search against the exact lexicographic one, collisions included."""

from __future__ import annotations

import numpy as np
import pytest

from torchmeshmetric.mpeg.sampling import grid_sampling as gs


@pytest.mark.parametrize("colour_width", [0, 3, 5])  # none, a colour, UV + colour (map and sdiv sampling)
def test_unique_vertex_rows_hash_matches_lexsort(colour_width: int, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(5)
    pos = (np.round(rng.random((3000, 3)) * 6) / 6).astype(np.float32)
    pos[::5] = -pos[::5] * 0  # -0.0 rows must merge with 0.0 rows
    pos[1::5] = 0.0
    nrm = np.round(rng.random((3000, 3))).astype(np.float32)
    nrm[3:5] = np.nan  # a NaN equals nothing: rows 3 and 4 are kept even where they are otherwise equal
    pos[4] = pos[3]
    col = rng.integers(0, 2, (3000, colour_width)).astype(np.float32) if colour_width else None
    keys = [pos, nrm] if col is None else [pos, nrm, col]
    want = gs._unique_rows_lexsort(keys)
    assert 0 < want.size < 3000
    np.testing.assert_array_equal(gs.unique_vertex_rows(pos, nrm, col), want)  # C++ where it can be built
    monkeypatch.setattr(gs, "_USE_NATIVE", False)
    np.testing.assert_array_equal(gs.unique_vertex_rows(pos, nrm, col), want)
    # every hash equal: the collision check must fall back to the exact lexicographic path
    monkeypatch.setattr(gs, "_row_hashes", lambda k: np.zeros(k[0].shape[0], np.uint64))
    np.testing.assert_array_equal(gs.unique_vertex_rows(pos, nrm, col), want)


def test_merge_native_equals_numpy(monkeypatch: pytest.MonkeyPatch) -> None:
    """The C++ merge equals the numpy one bit for bit: stable (x, y, z) order (-0.0 == 0.0), runs, sums in run order."""
    import torch

    from torchmeshmetric.mpeg.core import point_cloud as pc

    rng = np.random.default_rng(9)
    pos = (np.round(rng.random((4000, 3)) * 5) / 5).astype(np.float32)
    pos[::7] = -pos[::7] * 0
    cloud = pc.PointCloud(
        torch.from_numpy(pos),
        torch.from_numpy(rng.normal(size=(4000, 3)).astype(np.float32)),
        torch.from_numpy((rng.random((4000, 3)) * 255).astype(np.float32)),
    )
    from torchmeshmetric import native

    if native.try_load("pcc") is None:
        pytest.skip("C++ extension unavailable")
    got = pc.merge_duplicate_points(cloud)
    load = native.try_load
    monkeypatch.setattr(native, "try_load", lambda name: None if name == "pcc" else load(name))
    want = pc.merge_duplicate_points(cloud)
    assert 0 < want.num_points < 4000
    for name in ("points", "normals", "colors"):
        a, b = getattr(got, name).numpy(), getattr(want, name).numpy()
        np.testing.assert_array_equal(a.view(np.uint32), b.view(np.uint32))  # bit for bit, sign of zero included
