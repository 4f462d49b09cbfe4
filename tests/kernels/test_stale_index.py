"""A kept index never answers for a mesh that is gone: every form, every holder, refuses until refitted (issue 23).

Before: ``MeshIndex(verts, faces)`` kept the caller's tensor, so after ``verts.add_(...)`` (or ``optimizer.step()``
without ``refit``) ``point_mesh_distance`` answered for the old mesh and ``nearest_vertex_distance`` for the new one.
Now every form watches the tensors it was built from (torch's in-place version counters, no copy) and raises
``StaleIndexError`` naming the tensor; after ``refit`` the answers are a fresh index's, bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric import IndexCache, Mesh, MeshIndex, StaleIndexError
from torchmeshmetric.metrics import mesh_surface_distance_sets, nearest_vertex_distance_sets


def _sphere(dtype: torch.dtype = torch.float64) -> tuple[torch.Tensor, torch.Tensor]:
    m = trimesh.creation.icosphere(subdivisions=1)
    return torch.tensor(m.vertices, dtype=dtype), torch.tensor(m.faces)


def _points(n: int = 40, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    return torch.randn(n, 3, generator=torch.Generator().manual_seed(3), dtype=dtype) * 1.5


# Each form: (build the index from verts/faces, the vertex tensor the caller changes, its name in the error).
FORMS: dict[str, Callable[[torch.Tensor, torch.Tensor], tuple[MeshIndex, torch.Tensor, str]]] = {
    "tensor": lambda v, f: (MeshIndex(v, f), v, "verts"),
    "packed": lambda v, f: (
        MeshIndex(v, f, verts_lengths=torch.tensor([v.shape[0]]), faces_lengths=torch.tensor([f.shape[0]])),
        v,
        "verts",
    ),
    "tuple": lambda v, f: (MeshIndex((v, f)), v, "mesh.verts"),
    "Mesh": lambda v, f: (MeshIndex(Mesh(v, f)), v, "mesh.verts"),
    "list": lambda v, f: (MeshIndex([Mesh(v, f), Mesh(v.detach() * 2, f)]), v, r"mesh\[0\].verts"),
    "cache": lambda v, f: (IndexCache().get(Mesh(v, f)), v, "mesh.verts"),
    "cache-batch": lambda v, f: (IndexCache().get([Mesh(v, f), Mesh(v.detach() * 2, f)]), v, r"mesh\[0\].verts"),
}


def _query(index: MeshIndex, kind: str, points: torch.Tensor):
    if index.num_items == 2:
        points_list = [points, points]
        return (
            index.point_mesh_distance(points_list) if kind == "surface" else index.nearest_vertex_distance(points_list)
        )
    return index.point_mesh_distance(points) if kind == "surface" else index.nearest_vertex_distance(points)


def _change(verts: torch.Tensor, how: str) -> None:
    """Move ``verts`` in place the ways a training loop or a user does."""
    if how == "add_":
        with torch.no_grad():
            verts.add_(0.25)
    elif how == "setitem":
        with torch.no_grad():
            verts[0] = torch.tensor([3.0, 0.0, 0.0], dtype=verts.dtype)
    elif how in ("sgd", "adam"):
        opt = (torch.optim.SGD if how == "sgd" else torch.optim.Adam)([verts], lr=0.1)
        verts.grad = torch.ones_like(verts)
        opt.step()
    else:  # "copy_"
        with torch.no_grad():
            verts.copy_(verts * 1.5)


@settings(max_examples=60, deadline=None)
@given(
    form=st.sampled_from(sorted(FORMS)),
    kind=st.sampled_from(["surface", "vertex"]),
    how=st.sampled_from(["add_", "setitem", "sgd", "adam", "copy_"]),
    queried_before=st.booleans(),
    parameter=st.booleans(),
)
def test_a_changed_mesh_is_refused_until_refit(form, kind, how, queried_before, parameter):
    verts, faces = _sphere()
    if parameter or how in ("sgd", "adam"):
        verts = torch.nn.Parameter(verts)
    index, changed, name = FORMS[form](verts, faces)
    points = _points()
    if queried_before:  # the structures already built, or not yet: the same refusal
        _query(index, kind, points)
    _change(changed, how)
    for k in ("surface", "vertex"):  # both kinds refuse, whichever was asked first
        with pytest.raises(StaleIndexError, match=rf"^{name}: modified in place .*refit the index"):
            _query(index, k if kind == "surface" else {"surface": "vertex", "vertex": "surface"}[k], points)
    if form.startswith("cache"):
        return  # a cache's index is found again by content, never refitted: ask the cache again
    new = changed.detach() if index.num_items == 1 else torch.cat([changed.detach(), changed.detach() * 2])
    new = changed if index.num_items == 1 and parameter else new
    index.refit(new)
    fresh = (
        MeshIndex(new.detach().clone(), faces)
        if index.num_items == 1
        else MeshIndex([Mesh(changed.detach().clone(), faces), Mesh(changed.detach() * 2, faces)])
    )
    for k in ("surface", "vertex"):
        for a, b in zip(_query(index, k, points), _query(fresh, k, points), strict=True):
            assert torch.equal(a.detach(), b.detach())


@pytest.mark.parametrize("form", ["tensor", "tuple", "Mesh", "list"])
def test_changed_faces_are_refused_with_a_new_index_as_the_remedy(form):
    verts, faces = _sphere()
    index, _, _ = FORMS[form](verts, faces)
    index.point_mesh_distance(_points()) if index.num_items == 1 else None
    faces[[0, 1]] = faces[[1, 0]]  # in place: the caller's face tensor
    with pytest.raises(StaleIndexError, match=r"faces: modified in place .*build a new MeshIndex"):
        _query(index, "surface", _points())


def test_a_training_loop_that_refits_after_every_step_is_never_refused_and_gets_the_fresh_gradients():
    verts0, faces = _sphere()
    points = _points()
    param = torch.nn.Parameter(verts0.clone())
    opt = torch.optim.Adam([param], lr=0.01)
    index = MeshIndex(param, faces)
    for _ in range(4):
        opt.zero_grad()
        index.point_mesh_distance(points).dists.sum().backward()
        with torch.no_grad():
            fresh_param = param.detach().clone().requires_grad_()
        MeshIndex(fresh_param, faces).point_mesh_distance(points).dists.sum().backward()
        assert torch.equal(param.grad, fresh_param.grad)  # the index answers for the current mesh
        opt.step()
        with pytest.raises(StaleIndexError, match=r"after every optimizer\.step"):
            index.point_mesh_distance(points)
        index.refit(param)


def test_reading_the_version_costs_no_copy_and_good_input_is_unchanged():
    verts, faces = _sphere()
    index = MeshIndex(verts, faces)
    assert index.verts is verts  # the caller's tensor is kept, not copied
    points = _points()
    first = index.point_mesh_distance(points)
    again = index.point_mesh_distance(points)  # no change, no refusal, the same answer
    assert torch.equal(first.dists, again.dists)
    index.refit(verts)  # refitting to the same tensor is always allowed


@pytest.mark.parametrize("distance_sets", [mesh_surface_distance_sets, nearest_vertex_distance_sets])
@pytest.mark.parametrize("requires_grad", [False, True])
def test_a_prebuilt_index_of_a_changed_reference_is_refused_by_the_metrics(distance_sets, requires_grad):
    verts, faces = _sphere()
    ref = torch.nn.Parameter(verts.clone()) if requires_grad else verts.clone()
    index = MeshIndex(ref, faces)
    simplified = (verts * 1.1, faces)
    distance_sets(simplified, (ref, faces), reference_index=index, detach_reference=not requires_grad)
    _change(ref, "add_")
    with pytest.raises(StaleIndexError, match="verts: modified in place"):
        distance_sets(simplified, (ref, faces), reference_index=index, detach_reference=not requires_grad)


def test_the_cache_answers_for_the_content_it_is_keyed_by_after_the_first_callers_tensors_change():
    verts, faces = _sphere()
    cache = IndexCache()
    points = _points()
    first = cache.get((verts, faces))
    expected = first.point_mesh_distance(points)
    verts.mul_(3.0)  # the first caller's tensor changes: its copy refuses, the cached entry keeps its own copy
    with pytest.raises(StaleIndexError):
        first.point_mesh_distance(points)
    again = cache.get((verts / 3.0, faces))  # equal content to the first call: found, answers as before
    assert torch.equal(again.point_mesh_distance(points).dists, expected.dists)
    assert len(cache) == 1


def test_pickled_and_deep_copied_indexes_watch_their_own_tensors():
    import copy
    import pickle

    verts, faces = _sphere()
    index = MeshIndex(verts, faces)
    for other in (pickle.loads(pickle.dumps(index)), copy.deepcopy(index)):
        other.point_mesh_distance(_points())
        other.verts.add_(1.0)
        with pytest.raises(StaleIndexError):
            other.point_mesh_distance(_points())
    index.point_mesh_distance(_points())  # the original's tensors did not change


def test_with_verts_refuses_vertices_that_are_not_the_indexs():
    # Review V, F6: nothing was checked, so the copy answered for the index's mesh while autograd reached the new
    # tensor: with_verts(V + 1) gave 2.0 (the distance to V; V + 1 is at 1.4608), and a (10, 3) tensor was taken
    # for a 162-vertex index.
    from torchmeshmetric import DeviceError, DTypeError, ShapeError

    s = trimesh.creation.icosphere(subdivisions=2)
    verts, faces = torch.tensor(s.vertices), torch.tensor(s.faces)
    index = MeshIndex(verts, faces)
    q = torch.tensor([[0.0, 0, 3.0]])
    with pytest.raises(StaleIndexError, match=r"verts: expected vertices equal in value .* off by 1"):
        index.with_verts(verts + 1)
    with pytest.raises(ShapeError, match="verts"):
        index.with_verts(verts[:10])
    with pytest.raises(DTypeError, match="verts"):
        index.with_verts(verts.float())
    with pytest.raises(DeviceError, match="verts"):
        index.with_verts(verts.to("meta"))
    # Equal values (another tensor): accepted, and the gradient reaches it.
    v = verts.clone().requires_grad_()
    d = index.with_verts(v).point_mesh_distance(q).dists
    assert float(d.detach()) == float(index.point_mesh_distance(q).dists)
    d.sum().backward()
    assert v.grad is not None and float(v.grad.abs().sum()) > 0
