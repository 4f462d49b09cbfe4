import numpy as np
import pytest
import torch
import trimesh


def noisy_copy(mesh: trimesh.Trimesh, scale: float, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    rng = np.random.default_rng(seed)
    v = mesh.vertices + rng.normal(0, scale, mesh.vertices.shape)
    return torch.from_numpy(v), torch.from_numpy(mesh.faces)


@pytest.fixture
def frames():
    """Small reference meshes and "simplified" versions (perturbed, coarser), ragged sizes."""
    refs = [
        trimesh.creation.icosphere(subdivisions=2),
        trimesh.creation.capsule(height=1.0, radius=0.4, count=[12, 12]),
        trimesh.creation.box(extents=[1.0, 2.0, 0.5]).subdivide().subdivide(),
        trimesh.creation.torus(0.8, 0.2, major_sections=16, minor_sections=8),
    ]
    simps = [
        noisy_copy(trimesh.creation.icosphere(subdivisions=1), 0.02, 0),
        noisy_copy(trimesh.creation.capsule(height=1.0, radius=0.4, count=[6, 6]), 0.03, 1),
        noisy_copy(trimesh.creation.box(extents=[1.0, 2.0, 0.5]).subdivide(), 0.01, 2),
        noisy_copy(trimesh.creation.torus(0.8, 0.2, major_sections=8, minor_sections=4), 0.02, 3),
    ]
    return simps, refs
