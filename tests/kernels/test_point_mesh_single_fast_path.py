"""The batch-of-one path of point_mesh_distance matches the general packed path bit for bit, gradients included."""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric.kernels.point_triangle import point_mesh_distance


@pytest.mark.parametrize("backend", ["bruteforce", "bvh"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("requires_grad", [False, True])
def test_single_matches_packed(backend: str, dtype: torch.dtype, requires_grad: bool) -> None:
    mesh = trimesh.creation.icosphere(subdivisions=2)
    verts0 = torch.tensor(mesh.vertices, dtype=dtype) * 3 + 1e4
    faces = torch.tensor(mesh.faces)
    g = torch.Generator().manual_seed(0)
    points0 = torch.randn(300, 3, generator=g, dtype=dtype) * 4 + 1e4
    other_verts = torch.tensor(trimesh.creation.box().vertices, dtype=dtype)
    other_faces = torch.tensor(trimesh.creation.box().faces)
    results, grads = [], []
    for packed in (False, True):
        points, verts = points0.clone().requires_grad_(requires_grad), verts0.clone().requires_grad_(requires_grad)
        if packed:  # the same mesh as item 0 of a two-item batch
            r = point_mesh_distance(
                torch.cat([points, torch.zeros(5, 3, dtype=dtype)]),
                torch.cat([verts, other_verts]),
                torch.cat([faces, other_faces]),
                points_lengths=torch.tensor([300, 5]),
                verts_lengths=torch.tensor([len(verts0), len(other_verts)]),
                faces_lengths=torch.tensor([len(faces), len(other_faces)]),
                backend=backend,
            )
            r = type(r)(*(x[:300] for x in r))
        else:
            r = point_mesh_distance(points, verts, faces, backend=backend)
        results.append(r)
        if requires_grad:
            (r.dists * torch.linspace(0.5, 2.0, 300, dtype=dtype)).sum().backward()
            grads.append((points.grad, verts.grad))
    for name in ("dists", "face_idx", "bary", "closest"):
        assert torch.equal(getattr(results[0], name), getattr(results[1], name)), name
    if requires_grad:
        assert torch.equal(grads[0][0], grads[1][0]) and torch.equal(grads[0][1], grads[1][1])
