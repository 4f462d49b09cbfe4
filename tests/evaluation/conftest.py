import importlib.util

import pytest
import torch
import trimesh

from torchmeshmetric import Mesh

# The pipeline summarises every set with issue 3's distance_statistics; until that branch is merged here,
# every test of this folder is skipped (the module does not exist on this branch yet).
HAS_STATS = importlib.util.find_spec("torchmeshmetric.stats") is not None
collect_ignore_glob = [] if HAS_STATS else ["test_*.py"]


def sphere(subdivisions: int, radius: float = 1.0, offset=(0.0, 0.0, 0.0)) -> Mesh:
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    v = torch.tensor(m.vertices, dtype=torch.float64) + torch.tensor(offset, dtype=torch.float64)
    return Mesh(v, torch.tensor(m.faces))


class TranslationRegister:
    """A registration with a known answer: frames are unit spheres translated along x by 0.1 per frame, so the
    exact registration of frame k-1 onto frame k is the source translated by +0.1 in x. Counts its calls."""

    def __init__(self, step: float = 0.1) -> None:
        self.calls = 0
        self.step = step

    def __call__(self, source: Mesh, target: Mesh) -> Mesh:
        self.calls += 1
        shift = torch.tensor([self.step, 0.0, 0.0], dtype=source.verts.dtype)
        return Mesh(source.verts + shift, source.faces)


@pytest.fixture
def moving_spheres():
    """4 original frames (icosphere 2, translated 0.1 per frame) and their 'simplified' frames (icosphere 1)."""
    original = [sphere(2, offset=(0.1 * k, 0, 0)) for k in range(4)]
    simplified = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(4)]
    return original, simplified
