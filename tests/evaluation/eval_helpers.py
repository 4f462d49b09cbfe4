"""Shared helpers of the evaluation tests (known-answer meshes and registrations)."""

import torch
import trimesh

from torchmeshmetric import Mesh


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

    @property
    def cache_key(self) -> str:
        """What it computes, for a cache folder: an object has no lasting name of its own (registration_fn_name)."""
        return f"tests.TranslationRegister(step={self.step!r})"

    def __call__(self, source: Mesh, target: Mesh) -> Mesh:
        self.calls += 1
        shift = torch.tensor([self.step, 0.0, 0.0], dtype=source.verts.dtype)
        return Mesh(source.verts + shift, source.faces)
