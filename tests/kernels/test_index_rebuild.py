"""A kept structure whose tree has worn is rebuilt at its refit: faster queries, the same answers bit for bit.

:class:`~torchmeshmetric.kernels.select.Selector` rebuilds a refitted structure (``"bvh"``: faces and points) when its
area (summed node surface areas over the roots') has grown by ``REBUILD_AREA_GROWTH`` since its build, or after
``REBUILD_EVERY`` refits. The index only changes speed: these tests compare every answer (face, distance,
barycentrics, closest point; nearest vertex and its row) with a new index and with a refit-only one along twists and
training-like trajectories, ties included, and the losses' values and gradients with rebuilding at every step.
"""

from __future__ import annotations

import math
import sys

import pytest
import torch

from torchmeshmetric import Mesh, MeshIndex
from torchmeshmetric.kernels import select
from torchmeshmetric.kernels.accel.bvh import faces_area, points_area
from torchmeshmetric.kernels.kept_index import KeptIndex
from torchmeshmetric.metrics import MeshSurfaceDistanceLoss


def _mesh(dtype: torch.dtype) -> Mesh:
    from torchmeshmetric.data import demo_sequence

    frame = demo_sequence(1, resolution=32).frames[0]  # 1548 faces, a standing figure (long axis: y)
    return Mesh(frame.verts.to(dtype), frame.faces)


def _twist(v: torch.Tensor, degrees: float) -> torch.Tensor:
    """``v`` twisted about the vertical axis through its box centre: ``degrees`` at the top, 0 at the bottom."""
    lo, hi = v.amin(0), v.amax(0)
    angle = math.radians(degrees) * (v[:, 1] - lo[1]) / (hi[1] - lo[1])
    c = (lo + hi) / 2
    x, z = v[:, 0] - c[0], v[:, 2] - c[2]
    return torch.stack(
        [
            c[0] + x * torch.cos(angle) - z * torch.sin(angle),
            v[:, 1],
            c[2] + x * torch.sin(angle) + z * torch.cos(angle),
        ],
        1,
    )


def _queries(verts: torch.Tensor, faces: torch.Tensor, seed: int) -> torch.Tensor:
    """Random points around the mesh, its vertices (tied between their faces) and edge midpoints (two faces)."""
    g = torch.Generator().manual_seed(seed)
    lo, hi = verts.amin(0), verts.amax(0)
    random = lo + (hi - lo) * (1.4 * torch.rand(300, 3, generator=g, dtype=verts.dtype) - 0.2)
    return torch.cat([random, verts, (verts[faces[:, 0]] + verts[faces[:, 1]]) / 2])


def _answers(index: MeshIndex, points: torch.Tensor) -> list[torch.Tensor]:
    return [*index.point_mesh_distance(points), *index.nearest_vertex_distance(points)]


def _assert_same(got: list[torch.Tensor], want: list[torch.Tensor]) -> None:
    for g, w in zip(got, want, strict=True):
        assert torch.equal(g, w)


def test_a_tree_worn_by_a_large_twist_is_rebuilt_as_a_new_tree() -> None:
    mesh = _mesh(torch.float32)
    index = MeshIndex(mesh, backend="bvh")
    index.point_mesh_distance(mesh.verts[:1])
    index.nearest_vertex_distance(mesh.verts[:1])
    faces_tree, points_tree = index._faces.structure, index._nearest.selector.structure
    built = faces_area(faces_tree), points_area(points_tree)
    twisted = _twist(mesh.verts, 720)
    index.refit(twisted)
    fresh = MeshIndex(Mesh(twisted, mesh.faces), backend="bvh")
    _assert_same(_answers(index, twisted[:1]), _answers(fresh, twisted[:1]))  # builds the new index's trees
    # A refit to this pose grows the areas past the limit (measured: faces x1.6, points x1.9): both trees are rebuilt,
    # which is exactly the tree a new index builds on these vertices. Before, the refitted trees were kept.
    assert index._faces.structure is not faces_tree and index._nearest.selector.structure is not points_tree
    for got, want in zip(index._faces.structure, fresh._faces.structure, strict=True):
        assert torch.equal(got, want)
    for got, want in zip(index._nearest.selector.structure, fresh._nearest.selector.structure, strict=True):
        assert torch.equal(got, want)
    assert faces_area(faces_tree) > select.REBUILD_AREA_GROWTH * built[0]  # the old tree, refitted in place
    assert points_area(points_tree) > select.REBUILD_AREA_GROWTH * built[1]


def test_small_motions_keep_the_refitted_tree_until_the_every_n_rebuild(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(select, "REBUILD_EVERY", 3)
    mesh = _mesh(torch.float64)
    index = MeshIndex(mesh, backend="bvh")
    index.point_mesh_distance(mesh.verts[:1])
    g = torch.Generator().manual_seed(0)
    verts, trees = mesh.verts, []
    for _ in range(7):
        verts = verts + 1e-4 * torch.randn(verts.shape, generator=g, dtype=verts.dtype)
        index.refit(verts)
        trees.append(index._faces.structure)
    # Refits 1, 2 keep the built tree; the 3rd rebuilds; 4, 5 keep that one; the 6th rebuilds; the 7th keeps it.
    assert [t is trees[0] for t in trees[:3]] == [True, True, False]
    assert trees[3] is trees[2] and trees[4] is trees[2] and trees[5] is not trees[2] and trees[6] is trees[5]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("every", [2, 256])  # rebuilt often, and the default (rebuilt when the area has grown)
def test_answers_along_a_twist_are_those_of_a_new_index_and_of_a_refit_only_one(dtype, every, monkeypatch) -> None:
    mesh = _mesh(dtype)
    index = MeshIndex(mesh, backend="bvh")
    kept = MeshIndex(mesh, backend="bvh")  # refitted only: the path before
    rebuilt = 0
    for step, degrees in enumerate(range(0, 721, 60)):
        verts = _twist(mesh.verts, degrees) * (1 + 0.1 * step)
        points = _queries(verts, mesh.faces, step)
        before = index._faces.structure if index._faces is not None else None
        monkeypatch.setattr(select, "REBUILD_EVERY", every)
        index.refit(verts)
        rebuilt += before is not None and index._faces.structure is not before
        got = _answers(index, points)
        monkeypatch.setattr(select, "REBUILD_AREA_GROWTH", math.inf)
        monkeypatch.setattr(select, "REBUILD_EVERY", sys.maxsize)
        kept.refit(verts)
        _assert_same(got, _answers(kept, points))
        monkeypatch.undo()
        _assert_same(got, _answers(MeshIndex(Mesh(verts, mesh.faces), backend="bvh"), points))
    assert rebuilt >= 2  # the rebuild path is exercised (measured: 6 with every=2, 2 by area growth alone)


def test_a_batch_is_rebuilt_as_one_structure(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(select, "REBUILD_EVERY", 1)
    a, b = _mesh(torch.float64), _mesh(torch.float64)
    b = Mesh(b.verts[:, [2, 0, 1]] * 0.5, b.faces)
    index = MeshIndex([a, b], backend="bvh")
    for degrees in (90, 400):
        moved = [Mesh(_twist(a.verts, degrees), a.faces), Mesh(_twist(b.verts, -degrees), b.faces)]
        index.refit(torch.cat([m.verts for m in moved]))
        points = [_queries(m.verts, m.faces, degrees) for m in moved]
        lengths = torch.tensor([p.shape[0] for p in points])
        fresh = MeshIndex(moved, backend="bvh")
        got = [*index.point_mesh_distance(torch.cat(points), points_lengths=lengths)]
        got += [*index.nearest_vertex_distance(torch.cat(points), points_lengths=lengths)]
        want = [*fresh.point_mesh_distance(torch.cat(points), points_lengths=lengths)]
        want += [*fresh.nearest_vertex_distance(torch.cat(points), points_lengths=lengths)]
        _assert_same(got, want)


class _Rebuilt(KeptIndex):
    """A new index at every call."""

    def get(self, meshes: list[Mesh], backend: str) -> MeshIndex:
        self.index = None
        return super().get(meshes, backend)


def test_loss_values_and_gradients_are_those_of_rebuilding_every_step(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(select, "REBUILD_EVERY", 2)
    reference = _mesh(torch.float32)
    simplified = Mesh(reference.verts * 1.01, reference.faces)
    losses = {name: MeshSurfaceDistanceLoss(power=2, two_sided=True) for name in ("kept", "rebuilt")}
    losses["rebuilt"].options["indexes"].moving = _Rebuilt()
    for degrees in range(0, 721, 90):
        out = {}
        for name, loss_fn in losses.items():
            v = _twist(simplified.verts, degrees).requires_grad_(True)
            loss = loss_fn(Mesh(v, simplified.faces), reference)
            loss.backward()
            out[name] = (loss.detach(), v.grad)
        assert torch.equal(out["kept"][0], out["rebuilt"][0]) and torch.equal(out["kept"][1], out["rebuilt"][1])
