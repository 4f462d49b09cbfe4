"""Shared helpers of the CLI tests: a tiny translated-sphere sequence with a known exact registration."""

import torch
import trimesh

from torchmeshmetric import Mesh
from torchmeshmetric.registration import CachedRegistration

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
