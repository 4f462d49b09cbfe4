"""MeshIndex: the functions' answers and gradients bit for bit, refit without rebuild, batches, typed errors."""

from __future__ import annotations

import math
import sys

import pytest
import torch
import trimesh

from torchmeshmetric import MeshIndex, nearest_vertex_distance, point_mesh_distance, vertex_set
from torchmeshmetric._checks import DeviceError, DTypeError, NonFiniteError, ShapeError
from torchmeshmetric.kernels import select
from torchmeshmetric.kernels.triangle import closest_point_on_triangle
from torchmeshmetric.native import try_load


def _mesh(dtype: torch.dtype, offset: float = 0.0) -> tuple[torch.Tensor, torch.Tensor]:
    m = trimesh.creation.icosphere(subdivisions=3)
    verts = torch.tensor(m.vertices, dtype=dtype) * torch.tensor([1.0, 0.7, 1.3], dtype=dtype) + offset
    faces = torch.tensor(m.faces)
    # An unreferenced vertex (not in the vertex set) and a zero-area face on existing vertices.
    verts = torch.cat([verts, torch.full((1, 3), 5.0 + offset, dtype=dtype)])
    faces = torch.cat([faces, faces[:1, [0, 0, 1]]])
    return verts, faces


def _points(verts: torch.Tensor, n: int, seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    p = verts[torch.randint(0, verts.shape[0] - 1, (n,), generator=g)]
    return p + 0.05 * torch.randn(n, 3, generator=g, dtype=verts.dtype)


def _oracle(points: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """float64 all-pairs distances (independent of the selection code)."""
    p, v = points.double(), verts.double()
    tri = v[faces]
    sq = closest_point_on_triangle(p[:, None], tri[None, :, 0], tri[None, :, 1], tri[None, :, 2]).sq_dists
    return sq.amin(1).sqrt()


def _assert_same(a: tuple, b: tuple) -> None:
    for x, y in zip(a, b, strict=True):
        assert x.dtype == y.dtype and torch.equal(x.detach(), y.detach())


@pytest.mark.parametrize("backend", ["bvh", "bruteforce", "pruned"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("offset", [0.0, 1e5])
def test_index_equals_the_functions_bit_for_bit(backend: str, dtype: torch.dtype, offset: float) -> None:
    verts, faces = _mesh(dtype, offset)
    points = _points(verts, 300, 0)
    index = MeshIndex(verts, faces, backend=backend)
    for _ in range(2):  # the kept structure answers again, identically
        _assert_same(index.point_mesh_distance(points), point_mesh_distance(points, verts, faces, backend="bruteforce"))
        _assert_same(
            index.nearest_vertex_distance(points),
            nearest_vertex_distance(points, vertex_set((verts, faces)), backend="bruteforce"),
        )
    d = index.point_mesh_distance(points).dists.double()
    diag = float((verts.amax(0) - verts.amin(0)).norm())
    assert float((d - _oracle(points, verts, faces)).abs().max()) <= 2e-6 * diag


def test_index_gradients_equal_the_functions() -> None:
    verts0, faces = _mesh(torch.float64)
    points0 = _points(verts0, 200, 1)
    grads = []
    for use_index in (True, False):
        verts, points = verts0.clone().requires_grad_(), points0.clone().requires_grad_()
        if use_index:
            index = MeshIndex(verts, faces)
            for _ in range(2):  # each query has its own graph to the vertices
                loss = index.point_mesh_distance(points).dists.sum() + index.nearest_vertex_distance(points).dists.sum()
                loss.backward()
        else:
            for _ in range(2):
                loss = point_mesh_distance(points, verts, faces).dists.sum()
                loss = loss + nearest_vertex_distance(points, vertex_set((verts, faces))).dists.sum()
                loss.backward()
        grads.append((points.grad, verts.grad))
    assert torch.equal(grads[0][0], grads[1][0]) and torch.equal(grads[0][1], grads[1][1])


@pytest.mark.parametrize("backend", ["bvh", "bruteforce"])
def test_refit_is_exact_and_keeps_the_tree(backend: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # The refitted tree itself: a worn one is otherwise rebuilt (tests/kernels/test_index_rebuild.py).
    monkeypatch.setattr(select, "REBUILD_AREA_GROWTH", math.inf)
    monkeypatch.setattr(select, "REBUILD_EVERY", sys.maxsize)
    verts, faces = _mesh(torch.float32)
    index = MeshIndex(verts, faces, backend=backend)
    points = _points(verts, 400, 2)
    index.point_mesh_distance(points)
    index.nearest_vertex_distance(points)
    structure = index._faces.structure
    g = torch.Generator().manual_seed(3)
    for step in range(3):
        # A large non-rigid motion: the Morton order of the build is stale, the answers must not be.
        moved = verts * (1 + 0.5 * step) + 0.2 * torch.sin(3 * verts[:, [1, 2, 0]]) + torch.randn(3, generator=g)
        index.refit(moved)
        assert index._faces.structure is structure  # refitted in place, not rebuilt
        q = _points(moved, 400, 10 + step)
        _assert_same(index.point_mesh_distance(q), point_mesh_distance(q, moved, faces, backend="bruteforce"))
        _assert_same(
            index.nearest_vertex_distance(q),
            nearest_vertex_distance(q, vertex_set((moved, faces)), backend="bruteforce"),
        )


def test_refit_to_the_same_vertices_reproduces_the_built_tree() -> None:
    assert try_load("bvh") is not None
    verts, faces = _mesh(torch.float64)
    index = MeshIndex(verts, faces, backend="bvh")
    index.point_mesh_distance(verts[:5])
    index.nearest_vertex_distance(verts[:5])
    built = [t.clone() for t in index._faces.structure]
    built_points = [t.clone() for t in index._nearest.selector.structure]
    index.refit(verts * 3)
    index.refit(verts.clone())
    for a, b in zip(built + built_points, index._faces.structure + index._nearest.selector.structure, strict=True):
        assert torch.equal(a, b)


def test_batches_of_meshes() -> None:
    a = _mesh(torch.float64)
    b = _mesh(torch.float64, 3.0)
    b = (b[0][:-1] * 0.5, b[1][:-1])
    pa, pb = _points(a[0], 120, 4), _points(b[0], 80, 5)
    index = MeshIndex([a, b])
    got = index.point_mesh_distance([pa, pb])
    expected = point_mesh_distance([pa, pb], [a, b], backend="bruteforce")
    _assert_same(got, expected)
    ref = index.ref_points
    _assert_same(
        index.nearest_vertex_distance([pa, pb]),
        nearest_vertex_distance(
            torch.cat([pa, pb]), ref.points, points_lengths=torch.tensor([120, 80]), ref_lengths=ref.lengths
        ),
    )
    moved = index.verts * 1.1
    index.refit(moved)
    expected = point_mesh_distance(
        [pa, pb], [(moved[: a[0].shape[0]], a[1]), (moved[a[0].shape[0] :], b[1])], backend="bruteforce"
    )
    _assert_same(index.point_mesh_distance([pa, pb]), expected)


def test_typed_errors() -> None:
    verts, faces = _mesh(torch.float32)
    index = MeshIndex(verts, faces)
    # Wider points would be rounded to the index's float32: refused, saying how to build the index (the dtype rule).
    wider = r"points: expected an index of dtype torch\.float64 .*found one of dtype torch\.float32.*MeshIndex\("
    with pytest.raises(DTypeError, match=wider):
        index.point_mesh_distance(verts.double())
    with pytest.raises(DTypeError, match=wider.replace("points", r"points\[1\]")):
        index.nearest_vertex_distance([verts, verts.double()], points_lengths=None)
    with pytest.raises(DeviceError, match="index's device"):
        index.point_mesh_distance(torch.zeros(2, 3, device="meta"))
    with pytest.raises(ShapeError, match="verts"):
        index.refit(verts[:-1])
    with pytest.raises(DTypeError, match="verts"):
        index.refit(verts.double())
    bad = verts.clone()
    bad[3, 1] = float("nan")
    with pytest.raises(NonFiniteError, match="verts"):
        index.refit(bad)
    with pytest.raises(NonFiniteError, match="points"):
        index.point_mesh_distance(bad)
    with pytest.raises(ValueError, match="backend"):
        MeshIndex(verts, faces, backend="nope")


def test_index_cache_finds_an_index_by_content_and_keeps_gradients_to_the_given_vertices() -> None:
    from torchmeshmetric import IndexCache

    verts, faces = _mesh(torch.float64)
    cache = IndexCache(max_entries=2)
    a = cache.get((verts, faces))
    a.point_mesh_distance(verts[:3])
    assert cache.get((verts.clone(), faces.clone()))._faces.structure is a._faces.structure  # same content
    assert len(cache) == 1
    leaf = verts.clone().requires_grad_()
    p = _points(verts, 50, 7)
    cache.get((leaf, faces)).point_mesh_distance(p).dists.sum().backward()
    expected = verts.clone().requires_grad_()
    point_mesh_distance(p, expected, faces).dists.sum().backward()
    assert torch.equal(leaf.grad, expected.grad)
    cache.get((verts * 2, faces))
    cache.get((verts * 3, faces))
    assert len(cache) == 2  # least recently used dropped
    batch = cache.get([(verts, faces), (verts * 2, faces)])
    assert batch.num_items == 2


def test_pickled_index_answers_the_same() -> None:
    import pickle

    verts, faces = _mesh(torch.float32)
    index = MeshIndex(verts, faces)
    p = _points(verts, 100, 8)
    expected = index.point_mesh_distance(p)
    clone = pickle.loads(pickle.dumps(index))
    _assert_same(clone.point_mesh_distance(p), expected)


@pytest.mark.parametrize("case", ["lattice", "identical", "geometric", "random"])
def test_kept_sah_tree_selects_the_bruteforce_face(case: str) -> None:
    """A kept index builds a binned-SAH tree (the functions: Morton splits); the selection must be the same."""
    g = torch.Generator().manual_seed(9)
    if case == "lattice":  # integer lattice: exact ties and degenerate faces
        verts = torch.randn(60, 3, generator=g).mul(2).round()
        faces = torch.randint(0, 60, (200, 3), generator=g)
    elif case == "identical":  # every centroid equal: the object-median fallback
        verts = torch.randn(3, 3, generator=g)
        faces = torch.tensor([[0, 1, 2]]).repeat(50, 1)
    elif case == "geometric":  # exponentially spaced faces: lopsided SAH splits, the depth cap
        x = 2.0 ** torch.arange(-60.0, 60.0, dtype=torch.float64)
        verts = torch.stack([torch.stack([x, x * 0, x * 0], 1), torch.stack([x, x * 0 + 1, x * 0], 1)], 1)
        verts = torch.cat([verts.reshape(-1, 3), torch.zeros(1, 3, dtype=torch.float64)])
        n = x.numel()
        faces = torch.stack([torch.arange(n) * 2, torch.arange(n) * 2 + 1, torch.full((n,), 2 * n)], 1)
    else:
        verts = torch.randn(500, 3, generator=g, dtype=torch.float64)
        faces = torch.randint(0, 500, (2000, 3), generator=g)
    points = torch.randn(300, 3, generator=g, dtype=verts.dtype) * verts.abs().amax()
    index = MeshIndex(verts, faces, backend="bvh")
    _assert_same(index.point_mesh_distance(points), point_mesh_distance(points, verts, faces, backend="bruteforce"))
    index.refit(verts * 0.5)
    expected = point_mesh_distance(points, verts * 0.5, faces, backend="bruteforce")
    _assert_same(index.point_mesh_distance(points), expected)


@pytest.mark.parametrize("tree", ["sah", "morton"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_small_items_on_a_lattice_after_refit(dtype: torch.dtype, tree: str) -> None:
    """Items of 1, 2, 3, 5 and 9 faces (leaves that fill a block partly) with exact ties, before and after a refit."""
    g = torch.Generator().manual_seed(11)
    sizes = [1, 2, 3, 5, 9]
    verts = [torch.randint(-3, 4, (3 * n, 3), generator=g).to(dtype) for n in sizes]
    faces = [torch.randint(0, 3 * n, (n, 3), generator=g) for n in sizes]
    points = [torch.randint(-4, 5, (40, 3), generator=g).to(dtype) / 2 for _ in sizes]
    index = MeshIndex(list(zip(verts, faces, strict=True)), backend="bvh", tree=tree)
    for step in range(2):
        got = index.point_mesh_distance(points)
        for b in range(len(sizes)):
            ref = point_mesh_distance(points[b], verts[b], faces[b], backend="bruteforce")
            rows = slice(40 * b, 40 * (b + 1))
            assert torch.equal(got.face_idx[rows], ref.face_idx + sum(sizes[:b]))
            assert torch.equal(got.dists[rows], ref.dists)
        if step == 0:
            verts = [v.flip(0) * 2 for v in verts]  # every face moves: the tree is stale, the answers must not be
            index.refit(torch.cat(verts))
