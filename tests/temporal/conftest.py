from __future__ import annotations

import pytest
import torch
import trimesh


def animated_sphere(num_frames: int = 6, subdivisions: int = 1, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """A float64 icosphere whose vertices move smoothly (a wave plus a drift): ``(F, V, 3)`` and ``(T, 3)``."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    verts = torch.as_tensor(sphere.vertices, dtype=torch.float64)
    g = torch.Generator().manual_seed(seed)
    phase = torch.rand(verts.shape[0], 1, generator=g, dtype=torch.float64)
    frames = [
        verts * (1.0 + 0.05 * torch.sin(0.7 * k + 3.0 * verts[:, :1] + phase)) + torch.tensor([0.02 * k, 0.0, 0.01 * k])
        for k in range(num_frames)
    ]
    return torch.stack(frames), torch.as_tensor(sphere.faces, dtype=torch.int64)


@pytest.fixture
def sphere_animation() -> tuple[torch.Tensor, torch.Tensor]:
    return animated_sphere()
