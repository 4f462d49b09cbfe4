"""An index handed out by an IndexCache and refitted by its caller never moves what the cache (and others) share."""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric import IndexCache, MeshIndex


def _mesh() -> tuple[torch.Tensor, torch.Tensor]:
    m = trimesh.creation.icosphere(subdivisions=2)
    return torch.tensor(m.vertices, dtype=torch.float64), torch.tensor(m.faces)


def _points(verts: torch.Tensor, seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return verts[torch.randint(0, verts.shape[0], (100,), generator=g)] + 0.1 * torch.randn(
        100, 3, generator=g, dtype=verts.dtype
    )


def _answers(index: MeshIndex, points: torch.Tensor) -> tuple[torch.Tensor, ...]:
    faces = index.point_mesh_distance(points)
    near = index.nearest_vertex_distance(points)
    return faces.dists, faces.face_idx, near.dists, near.idx


def _assert_same(got: tuple[torch.Tensor, ...], want: tuple[torch.Tensor, ...]) -> None:
    for g, w in zip(got, want, strict=True):
        assert torch.equal(g, w)


@pytest.mark.parametrize("backend", ["auto", "bruteforce", "pruned"])
@pytest.mark.parametrize("queried_before", [True, False])
def test_refit_of_a_cached_copy_leaves_the_cache_entry_and_other_copies_alone(backend, queried_before):
    verts, faces = _mesh()
    moved = verts * torch.tensor([1.5, 0.5, 1.0], dtype=verts.dtype) + 0.3  # far from the original
    points = _points(verts, 0)
    want_original = _answers(MeshIndex(verts, faces, backend=backend), points)
    want_moved = _answers(MeshIndex(moved, faces, backend=backend), points)
    cache = IndexCache()
    other = cache.get((verts, faces), backend=backend)  # another holder of the same entry
    mine = cache.get((verts.clone(), faces.clone()), backend=backend)
    if queried_before:  # the structures exist (built on the entry) before the refit
        _assert_same(_answers(mine, points), want_original)
    mine.refit(moved)
    _assert_same(_answers(mine, points), want_moved)  # the refitted copy answers for the moved mesh
    _assert_same(_answers(other, points), want_original)  # ... and nobody else does
    _assert_same(_answers(cache.get((verts, faces), backend=backend), points), want_original)
    mine.refit(moved * 1.1)  # a second refit of the (now own) structures: still exact, still private
    _assert_same(_answers(mine, points), _answers(MeshIndex(moved * 1.1, faces, backend=backend), points))
    _assert_same(_answers(other, points), want_original)
