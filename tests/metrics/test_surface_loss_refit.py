"""MeshSurfaceDistanceLoss keeps the simplified mesh's index and refits it: the same bits as a rebuild, never stale.

Before, every two-sided training step built a new index of the simplified mesh (about 45 % of the step,
``tests/benchmarks/surface_loss_refit.py``); the loss's :class:`~torchmeshmetric.IndexCache` now keeps it
(``moving``) and refits it while the faces stay the same. The function without a cache still builds a one-off index
at every call: the two are compared bit for bit, values (per point) and gradients, along training runs.
"""

from __future__ import annotations

import copy
import gc
import pickle
import weakref
from collections.abc import Callable

import pytest
import torch
import trimesh

from torchmeshmetric import Mesh, StaleIndexError
from torchmeshmetric.metrics import MeshSurfaceDistanceLoss, mesh_surface_distance_loss

OPTIONS = {"power": 2, "reduction": "none", "two_sided": True}


def _reference() -> Mesh:
    m = trimesh.creation.icosphere(subdivisions=3)
    return Mesh(torch.tensor(m.vertices) * torch.tensor([1.0, 0.8, 1.2], dtype=torch.float64), torch.tensor(m.faces))


def _simplified(dtype: torch.dtype = torch.float64, subdivisions: int = 2) -> tuple[torch.Tensor, torch.Tensor]:
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    g = torch.Generator().manual_seed(subdivisions)
    verts = torch.tensor(m.vertices, dtype=dtype) * (1 + 0.05 * torch.rand(len(m.vertices), 1, generator=g))
    return verts.to(dtype), torch.tensor(m.faces)


def _both(simplified: object, reference: object, loss: MeshSurfaceDistanceLoss, leaves: list[torch.Tensor]) -> None:
    """The module's terms and gradients equal the function's (a one-off index each call), bit for bit."""
    got = loss(simplified, reference)
    want = mesh_surface_distance_loss(simplified, reference, **OPTIONS)
    assert torch.equal(got, want)
    for g, w in zip(torch.autograd.grad(got.sum(), leaves), torch.autograd.grad(want.sum(), leaves), strict=True):
        assert torch.equal(g, w)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_a_training_run_refits_and_gives_the_rebuild_s_bits(dtype):
    reference = _reference()  # float64: a float32 simplified mesh is promoted (a cast copy each step)
    verts, faces = _simplified(dtype)
    verts.requires_grad_(True)
    loss = MeshSurfaceDistanceLoss(**OPTIONS)
    _both((verts, faces), reference, loss, [verts])
    index = loss.options["indexes"].moving.index
    assert index is not None
    g = torch.Generator().manual_seed(0)
    for step, size in enumerate([1e-6, 1e-3, 1e-2, 0.1, 0.5, 1e-4]):  # steps of several sizes, one run
        with torch.no_grad():
            verts += size * torch.randn(verts.shape, generator=g, dtype=dtype)
        _both((verts, faces), reference, loss, [verts])
        assert loss.options["indexes"].moving.index is index, step  # refitted, not rebuilt


def test_an_optimiser_loop_gives_the_rebuild_s_trajectory():
    reference = _reference()
    start, faces = _simplified()
    runs = []
    for keep in (True, False):
        verts = start.clone().requires_grad_(True)
        opt = torch.optim.Adam([verts], lr=0.02)
        loss = MeshSurfaceDistanceLoss(power=2, two_sided=True)
        trajectory = []
        for _ in range(8):
            opt.zero_grad()
            value = (
                loss(Mesh(verts, faces), reference)
                if keep
                else mesh_surface_distance_loss(Mesh(verts, faces), reference, power=2, two_sided=True)
            )
            value.backward()
            opt.step()  # in place: the kept index is refitted to the new vertices at the next call
            trajectory.append((value.detach(), verts.detach().clone()))
        runs.append(trajectory)
    for (a, va), (b, vb) in zip(*runs, strict=True):
        assert torch.equal(a, b) and torch.equal(va, vb)


def test_a_batch_and_faces_that_change_between_calls():
    reference = _reference()
    (v1, f1), (v2, f2) = _simplified(subdivisions=1), _simplified(subdivisions=2)
    v1.requires_grad_(True)
    v2.requires_grad_(True)
    loss = MeshSurfaceDistanceLoss(**OPTIONS)
    rolled = f2[:, [1, 2, 0]]  # the same triangles, corners rotated: other faces for an index
    flipped = f2.clone()
    flipped[[0, 5]] = flipped[[5, 0]]
    calls: list[tuple[object, object, list[torch.Tensor]]] = [
        ([(v1, f1), (v2, f2)], [reference, reference], [v1, v2]),
        ([(v1, f1), (v2, f2)], [reference, reference], [v1, v2]),  # same faces: refit
        ((v2, f2), reference, [v2]),  # one item: another batch
        ((v2, rolled), reference, [v2]),
        ((v2, flipped), reference, [v2]),
        ((v1, f1), reference, [v1]),  # other counts
        ((v2, f2), reference, [v2]),
    ]
    built = []
    for simplified, ref, leaves in calls:
        _both(simplified, ref, loss, leaves)
        built.append(loss.options["indexes"].moving.index)
    assert built[1] is built[0]
    assert len({id(b) for b in built[1:]}) == len(built) - 1  # every change of faces built a new index


def test_in_place_edits_between_calls_never_serve_a_stale_index():
    reference = _reference()
    verts, faces = _simplified()
    verts.requires_grad_(True)
    loss = MeshSurfaceDistanceLoss(**OPTIONS)
    _both((verts, faces), reference, loss, [verts])
    edits: list[Callable[[], object]] = [
        lambda: verts.data.mul_(1.1),  # a write torch does not count
        lambda: verts.detach().add_(0.05),  # counted, through a view
        lambda: faces.add_(
            0
        ),  # the faces edited in place, equal values: refit (was StaleIndexError in the temporal loss)
        lambda: faces.copy_(faces[:, [0, 2, 1]]),  # edited in place, other values: a new index
    ]
    for edit in edits:
        with torch.no_grad():
            edit()
        _both((verts, faces), reference, loss, [verts])


def test_fused_adam_steps_are_seen():
    """``fused=True`` writes without counting: the vertices are refitted from their values at every call anyway."""
    reference = _reference()
    verts, faces = _simplified(torch.float32)
    verts.requires_grad_(True)
    try:
        opt = torch.optim.Adam([verts], lr=0.05, fused=True)
    except (RuntimeError, TypeError) as e:  # no fused CPU kernel in this torch
        pytest.skip(str(e))
    loss = MeshSurfaceDistanceLoss(**OPTIONS)
    for _ in range(3):
        _both((verts, faces), reference, loss, [verts])
        loss(Mesh(verts, faces), reference).sum().backward()
        opt.step()
        opt.zero_grad()


def test_no_graph_is_kept_and_the_kept_index_does_not_grow():
    reference = _reference()
    verts, faces = _simplified(torch.float32)  # promoted: the loss measures a float64 copy with a graph
    verts.requires_grad_(True)
    loss = MeshSurfaceDistanceLoss(power=2, two_sided=True)
    sizes = []
    for step in range(4):
        moved = verts * (1 + 0.01 * step)  # a non-leaf of this step's graph
        alive = weakref.ref(moved)
        loss(Mesh(moved, faces), reference).backward()
        del moved
        gc.collect()
        assert alive() is None  # nothing between steps holds the step's tensors (nor their graph)
        held = [t for t in _tensors(loss.options["indexes"].moving)]
        assert not any(t.requires_grad or t.grad_fn is not None for t in held)
        sizes.append(
            sum(t.untyped_storage().nbytes() for t in {t.untyped_storage().data_ptr(): t for t in held}.values())
        )
    assert len(set(sizes[1:])) == 1


def _tensors(obj: object, seen: set[int] | None = None) -> list[torch.Tensor]:
    """Every tensor reachable from ``obj`` through attributes, lists, tuples and dicts."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return []
    seen.add(id(obj))
    if isinstance(obj, torch.Tensor):
        return [obj]
    if isinstance(obj, dict):
        children = list(obj.values())
    elif isinstance(obj, (list, tuple)):
        children = list(obj)
    elif hasattr(obj, "__dict__") and not callable(obj):
        children = list(vars(obj).values())
    else:
        children = []
    return [t for c in children for t in _tensors(c, seen)]


def test_state_dict_pickle_and_deepcopy_are_unchanged():
    reference = _reference()
    verts, faces = _simplified()
    verts.requires_grad_(True)
    fresh = MeshSurfaceDistanceLoss(**OPTIONS)
    trained = MeshSurfaceDistanceLoss(**OPTIONS)
    for _ in range(2):
        trained(Mesh(verts, faces), reference).sum().backward()
    assert trained.state_dict() == fresh.state_dict() == {}
    assert pickle.dumps(trained) == pickle.dumps(fresh)  # the caches pickle empty, as before
    for other in (pickle.loads(pickle.dumps(trained)), copy.deepcopy(trained)):
        assert other.options["indexes"].moving.index is None
        _both((verts, faces), reference, other, [verts])
        assert other.options["indexes"].moving.index is not None


def test_without_gradient_the_one_off_path_is_kept():
    """Under ``no_grad`` the reverse set is the function's (no index is built), as before: nothing is kept."""
    reference = _reference()
    verts, faces = _simplified()
    loss = MeshSurfaceDistanceLoss(**OPTIONS)
    with torch.no_grad():
        got = loss((verts, faces), reference)
    assert loss.options["indexes"].moving.index is None
    assert torch.equal(got, mesh_surface_distance_loss((verts, faces), reference, **OPTIONS))


def test_a_stale_prebuilt_simplified_index_is_still_refused():
    """A caller's own ``simplified_index`` is used as given (not refitted): an in-place edit still raises."""
    from torchmeshmetric import MeshIndex

    reference = _reference()
    verts, faces = _simplified()
    index = MeshIndex(verts, faces)
    with torch.no_grad():
        verts.add_(0.01)
    with pytest.raises(StaleIndexError):
        mesh_surface_distance_loss(
            (verts.requires_grad_(True), faces), reference, two_sided=True, simplified_index=index
        )
