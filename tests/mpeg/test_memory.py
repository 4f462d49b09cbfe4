"""Memory goal: a grid sampling of ~1.7 M points needs a few hundred MB at most (rays are tested in chunks)."""

from __future__ import annotations

import tracemalloc

import pytest

from tests.mpeg.conftest import MPEG_REF
from torchmeshmetric.data.io import load_mesh
from torchmeshmetric.mpeg import grid_sample


def test_grid_sampling_memory() -> None:
    """Peak traced (numpy) memory of one ~1.7 M-point grid sampling: a few hundred MB at most."""
    path = MPEG_REF / "torus" / "ref.obj"
    if not path.is_file():
        pytest.skip("../shared/reference/mpeg absent")
    mesh = load_mesh(path)
    tracemalloc.start()
    cloud = grid_sample(mesh, 1024, box=([-1.35, -1.35, -0.35], [1.35, 1.35, 0.35]))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    print(f"\ngrid sampling of {cloud.num_points} points: peak {peak / 2**20:.0f} MiB")
    assert cloud.num_points > 1_600_000
    assert peak < 400 * 2**20
