"""KeptIndex: a refitted index answers what a new one answers, bit for bit (ties included), and is never stale.

The losses keep the index of the meshes they learn (``kernels/kept_index.py``) and refit it while the faces stay the
same. These tests move random meshes by steps of several sizes, change their faces, and edit their tensors in place
between calls, and compare every answer (selected face, distance, barycentrics, closest point) with an index built
afresh, with the same backend and with the brute-force backend (the contract's choice among ties).
"""

from __future__ import annotations

import math
import pickle
import sys

import pytest
import torch
import trimesh

from torchmeshmetric import Mesh, MeshIndex
from torchmeshmetric.kernels import select
from torchmeshmetric.kernels.kept_index import KeptIndex
from torchmeshmetric.kernels.triangle import closest_point_on_triangle_unchecked

BACKENDS = ["auto", "bruteforce", "pruned"]


def _sphere(subdivisions: int, seed: int, dtype: torch.dtype) -> Mesh:
    """A perturbed icosphere (convex-ish, so that points pushed out of a vertex tie between its faces)."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    g = torch.Generator().manual_seed(seed)
    verts = torch.tensor(m.vertices, dtype=dtype)
    verts = verts * (1 + 0.02 * torch.rand(verts.shape[0], 1, generator=g, dtype=dtype))
    return Mesh(verts, torch.tensor(m.faces))


def _soup(num_verts: int, num_faces: int, seed: int, dtype: torch.dtype) -> Mesh:
    """Random triangles over random vertices (intersecting, degenerate faces possible)."""
    g = torch.Generator().manual_seed(seed)
    verts = torch.randn(num_verts, 3, generator=g, dtype=dtype)
    return Mesh(verts, torch.randint(0, num_verts, (num_faces, 3), generator=g))


def _queries(mesh: Mesh, seed: int) -> torch.Tensor:
    """Random points, and points made to tie: the vertices (distance 0 to every incident face), the vertices pushed
    out radially (a vertex region shared by its faces), edge midpoints (two faces)."""
    g = torch.Generator().manual_seed(seed)
    v, f = mesh.verts.detach(), mesh.faces
    lo, hi = v.amin(0), v.amax(0)
    random = lo + (hi - lo) * torch.rand(200, 3, generator=g, dtype=v.dtype) * 1.4 - 0.2 * (hi - lo)
    centre = v.mean(0)
    return torch.cat([random, v, centre + 1.5 * (v - centre), (v[f[:, 0]] + v[f[:, 1]]) / 2])


def _answers(index: MeshIndex, points: torch.Tensor, lengths: torch.Tensor) -> tuple[torch.Tensor, ...]:
    return tuple(index.point_mesh_distance(points, points_lengths=lengths))


def _assert_equal(got: tuple[torch.Tensor, ...], want: tuple[torch.Tensor, ...]) -> None:
    for g, w in zip(got, want, strict=True):
        assert torch.equal(g, w)


def _ties(index: MeshIndex, points: torch.Tensor, lengths: torch.Tensor) -> int:
    """Points whose least computed squared distance (the index's frame, all faces) is reached by several faces."""
    hit = index.point_mesh_distance_centred(points, lengths)
    tri = index.centred_verts()[index.faces]  # one mesh: local rows are global
    sq = closest_point_on_triangle_unchecked(hit.points_c[:, None], tri[:, 0], tri[:, 1], tri[:, 2]).sq_dists
    return int(((sq == sq.amin(1, keepdim=True)).sum(1) > 1).sum())


def _step(verts: torch.Tensor, size: float, seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    extent = float((verts.amax(0) - verts.amin(0)).norm())
    return verts + size * extent * torch.randn(verts.shape, generator=g, dtype=verts.dtype)


@pytest.mark.parametrize(
    ("backend", "dtype", "kind"),
    [
        *[("auto", d, k) for d in (torch.float32, torch.float64) for k in ("sphere", "soup")],
        ("bruteforce", torch.float64, "sphere"),  # the other CPU backends, on one case each (the suite's time)
        ("pruned", torch.float32, "soup"),
    ],
)
def test_refitted_answers_are_those_of_a_new_index_bit_for_bit_ties_included(backend, dtype, kind, monkeypatch):
    # The refitted tree itself, however stale: worn trees are otherwise rebuilt (tests/kernels/test_index_rebuild.py).
    monkeypatch.setattr(select, "REBUILD_AREA_GROWTH", math.inf)
    monkeypatch.setattr(select, "REBUILD_EVERY", sys.maxsize)
    mesh = _sphere(2, 0, dtype) if kind == "sphere" else _soup(60, 150, 0, dtype)
    kept = KeptIndex()
    first = kept.get([mesh], backend)
    verts, ties = mesh.verts, 0
    # Steps of several sizes, one after the other: the tree is refitted again and again, never rebuilt.
    for step, size in enumerate([0.0, 1e-7, 1e-4, 1e-2, 0.1, 1.0, 1e-3, 10.0]):
        verts = _step(verts, size, step)
        moved = Mesh(verts, mesh.faces)
        index = kept.get([moved], backend)
        assert index is first  # refitted, not rebuilt
        points = _queries(moved, step)
        lengths = torch.tensor([points.shape[0]])
        got = _answers(index, points, lengths)
        _assert_equal(got, _answers(MeshIndex(moved, backend=backend), points, lengths))
        if backend != "bruteforce":  # the contract's choice among equal computed squares, made plainly
            assert torch.equal(got[1], _answers(MeshIndex(moved, backend="bruteforce"), points, lengths)[1])
        ties += _ties(index, points, lengths)
    assert ties > 100  # the case exercises ties (measured: thousands over the steps)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_batch_is_refitted_as_one_index(backend):
    meshes = [_sphere(2, 1, torch.float64), _soup(40, 90, 1, torch.float64)]
    kept = KeptIndex()
    first = kept.get(meshes, backend)
    for step, size in enumerate([1e-3, 0.3]):
        meshes = [Mesh(_step(m.verts, size, step + 10 * i), m.faces) for i, m in enumerate(meshes)]
        points = [_queries(m, step) for m in meshes]
        lengths = torch.tensor([p.shape[0] for p in points])
        assert kept.get(meshes, backend) is first
        _assert_equal(
            _answers(first, torch.cat(points), lengths),
            _answers(MeshIndex(meshes, backend=backend), torch.cat(points), lengths),
        )


def test_changed_faces_counts_dtype_device_or_backend_build_a_new_index():
    mesh = _sphere(2, 2, torch.float64)
    kept = KeptIndex()
    index = kept.get([mesh], "auto")
    points = _queries(mesh, 0)
    lengths = torch.tensor([points.shape[0]])
    flipped = mesh.faces.clone()
    flipped[[0, 1]] = flipped[[1, 0]]  # same faces in another order: other rows, another index
    changes = [
        Mesh(mesh.verts, flipped),
        Mesh(mesh.verts, mesh.faces[:-1]),  # a face fewer
        Mesh(torch.cat([mesh.verts, mesh.verts[:1]]), mesh.faces),  # a vertex more (unreferenced)
        Mesh(mesh.verts.float(), mesh.faces),  # another dtype
    ]
    for changed in changes:
        new = kept.get([changed], "auto")
        assert new is not index
        index = new
        p = points.to(changed.verts.dtype)
        _assert_equal(_answers(new, p, lengths), _answers(MeshIndex(changed), p, lengths))
    assert kept.get([changes[-1]], "bruteforce") is not index  # another backend


def test_equal_faces_in_a_new_tensor_refit_and_the_same_tensor_edited_in_place_is_compared():
    mesh = _sphere(2, 3, torch.float64)
    faces = mesh.faces.clone()
    kept = KeptIndex()
    index = kept.get([Mesh(mesh.verts, faces)], "auto")
    assert kept.get([Mesh(mesh.verts * 1.1, faces.clone())], "auto") is index  # equal content, new tensor: refit
    faces.add_(0)  # in place, equal values: still the same faces (was a StaleIndexError in the temporal loss)
    moved = Mesh(mesh.verts * 1.2, faces)
    assert kept.get([moved], "auto") is index
    points = _queries(moved, 1)
    lengths = torch.tensor([points.shape[0]])
    _assert_equal(_answers(index, points, lengths), _answers(MeshIndex(moved), points, lengths))
    faces[[0, 1]] = faces[[1, 0]].clone()  # in place, other values: a new index
    index = kept.get([Mesh(mesh.verts, faces)], "auto")
    _assert_equal(_answers(index, points, lengths), _answers(MeshIndex(Mesh(mesh.verts, faces)), points, lengths))


def test_vertices_edited_in_place_between_calls_are_never_served_stale():
    mesh = _sphere(2, 4, torch.float64)
    verts = mesh.verts.clone().requires_grad_(True)
    kept = KeptIndex()
    index = kept.get([Mesh(verts, mesh.faces)], "auto")
    points = _queries(mesh, 2)
    lengths = torch.tensor([points.shape[0]])
    edits = [
        lambda: verts.data.mul_(1.5),  # a write torch does not count (no version bump)
        lambda: verts.detach().add_(0.3),  # counted, through a view
        lambda: torch.optim.SGD([verts], lr=0.1).step(),  # counted (the gradient set below)
    ]
    for edit in edits:
        verts.grad = torch.ones_like(verts)
        with torch.no_grad():
            edit()
        assert kept.get([Mesh(verts, mesh.faces)], "auto") is index
        fresh = MeshIndex(Mesh(verts.detach().clone(), mesh.faces))
        _assert_equal(_answers(index, points, lengths), _answers(fresh, points, lengths))


def test_the_index_holds_no_graph_and_pickles_empty():
    mesh = _sphere(2, 5, torch.float64)
    verts = (mesh.verts.clone().requires_grad_(True) * 2)[:, [0, 1, 2]]  # a non-leaf with a graph
    kept = KeptIndex()
    index = kept.get([Mesh(verts, mesh.faces)], "auto")
    index.point_mesh_distance(mesh.verts)
    assert not index.verts.requires_grad and index.verts.grad_fn is None
    state = pickle.loads(pickle.dumps(kept))
    assert state.index is None and state.faces is None and state.sources == []
