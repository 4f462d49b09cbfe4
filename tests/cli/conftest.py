import importlib.util

import pytest
import torch
import trimesh

from torchmeshmetric import Mesh
from torchmeshmetric.evaluation import CachedRegistration

# The CLI reads frames with issue 4's torchmeshmetric.data and summarises with issue 3's torchmeshmetric.stats;
# until both are merged into this branch the CLI tests are skipped (the modules do not exist here yet).
_NEEDED = ("torchmeshmetric.stats", "torchmeshmetric.data")
collect_ignore_glob = [] if all(importlib.util.find_spec(m) for m in _NEEDED) else ["test_*.py"]

STEP = 0.1


def write_frames(folder, subdivisions, n=3, corrupt=None):
    folder.mkdir()
    for k in range(n):
        m = trimesh.creation.icosphere(subdivisions=subdivisions)
        m.apply_translation([STEP * k, 0, 0])
        m.export(folder / f"frame_{k:02d}.ply")
    return folder


class Counting:
    """Known exact registration of these frames (translation by STEP along x); counts calls."""

    def __init__(self):
        self.calls = 0

    def __call__(self, source: Mesh, target: Mesh, *, device=None, **options) -> CachedRegistration:
        self.calls += 1
        verts = source.verts + torch.tensor([STEP, 0, 0], dtype=source.verts.dtype)
        return CachedRegistration(verts, torch.zeros(source.num_verts, dtype=verts.dtype), True, 0.0)


@pytest.fixture
def known_registration(monkeypatch):
    """Replace the default (non-rigid) registration by the exact one so CLI tests test the CLI, fast."""
    fn = Counting()
    monkeypatch.setattr("torchmeshmetric.evaluation.pipeline.default_register", fn)
    monkeypatch.setattr("torchmeshmetric.evaluation.default_register", fn)
    return fn


@pytest.fixture
def sequence(tmp_path):
    return write_frames(tmp_path / "orig", 2), write_frames(tmp_path / "simp", 1)
