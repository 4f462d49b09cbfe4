"""``IndexCache`` hashes the same unchanged tensors once, and hashes again whenever torch cannot vouch for them.

Before, :meth:`IndexCache.get` hashed the whole mesh at every call (a host copy: on CUDA a device-to-host copy and a
sync), 1.7 ms of a 15-18 ms two-sided ``NearestVertexDistanceLoss`` step at the demo's resolution 160. It now
remembers the key of the last tensors it hashed (weak references, version counters, storage flags): the tests count
the calls of :func:`content_key` and compare every answer with a new ``MeshIndex`` of the mesh, bit for bit.
"""

from __future__ import annotations

import copy
import gc
import pickle
import weakref
from collections.abc import Iterator

import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import IndexCache, Mesh, MeshIndex
from torchmeshmetric.kernels import index_cache
from torchmeshmetric.metrics import MeshSurfaceDistanceLoss, NearestVertexDistanceLoss

POINTS = torch.tensor([[0.0, 0.0, 2.0], [0.3, -1.2, 0.1], [0.05, 0.02, 0.01], [1.5, 1.5, -1.5]], dtype=torch.float64)


def _sphere(subdivisions: int = 2) -> tuple[torch.Tensor, torch.Tensor]:
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return torch.tensor(m.vertices), torch.tensor(m.faces)


@pytest.fixture
def hashes(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """The number of :func:`content_key` calls so far (one element, updated in place)."""
    count = [0]
    real = index_cache.content_key

    def counted(meshes: list[Mesh], salt: str) -> str:
        count[0] += 1
        return real(meshes, salt)

    monkeypatch.setattr(index_cache, "content_key", counted)
    yield count


def _answers(index: MeshIndex) -> tuple[torch.Tensor, ...]:
    points = POINTS if index.num_items == 1 else [POINTS] * index.num_items
    faces, near = index.point_mesh_distance(points), index.nearest_vertex_distance(points)
    return faces.dists, faces.face_idx, near.dists, near.idx


def _assert_answers_for(index: MeshIndex, mesh: object) -> None:
    """``index`` answers what a new index of ``mesh`` answers, bit for bit (never the answers of a mesh gone)."""
    for got, want in zip(_answers(index), _answers(MeshIndex(mesh)), strict=True):  # type: ignore[arg-type]
        assert torch.equal(got, want)


def test_the_same_tensors_are_hashed_once_across_steps(hashes):
    verts, faces = _sphere()
    cache = IndexCache()
    for step in range(6):  # a new Mesh or tuple around the same tensors at every step, as a training loop makes
        mesh = Mesh(verts, faces) if step % 2 else (verts, faces)
        index = cache.get(mesh)
        _assert_answers_for(index, (verts, faces))
    assert hashes[0] == 1  # was 6: one hash per call
    assert len(cache) == 1


def test_an_in_place_edit_is_hashed_again_and_answered_for(hashes):
    verts, faces = _sphere()
    cache = IndexCache()
    cache.get((verts, faces))
    with torch.no_grad():
        verts.mul_(torch.tensor([1.5, 0.5, 1.0], dtype=verts.dtype))  # counted by torch: the version moves
    _assert_answers_for(cache.get((verts, faces)), (verts.clone(), faces))
    assert hashes[0] == 2
    verts[:5] += 0.25  # indexing writes are counted too (the first vertices only: same shape, same pointer)
    _assert_answers_for(cache.get(Mesh(verts, faces)), (verts.clone(), faces))
    half = faces.shape[0] // 2
    faces[:half, 2] = faces[:half, 1]  # half the triangles collapse to an edge: another surface, the same tensor
    _assert_answers_for(cache.get((verts, faces)), (verts.clone(), faces.clone()))
    assert hashes[0] == 4 and len(cache) == 4
    cache.get((verts, faces))
    assert hashes[0] == 4  # unchanged since: remembered again


def test_a_write_through_a_view_or_the_base_is_seen(hashes):
    # Views share their base's version counter: a write through either is a change of the other.
    base = _sphere()[0].clone()
    faces = _sphere()[1]
    verts = base[:]  # a view
    cache = IndexCache()
    cache.get((verts, faces))
    base.detach()[0, 0] = 0.5  # detach() shares the counter as well
    _assert_answers_for(cache.get((verts, faces)), (verts.clone(), faces))
    assert hashes[0] == 2


def test_new_tensors_are_hashed_equal_content_finds_the_entry(hashes):
    verts, faces = _sphere()
    cache = IndexCache()
    first = cache.get((verts, faces))
    again = cache.get((verts.clone(), faces.clone()))  # equal content, new tensors: hashed, the same entry
    assert hashes[0] == 2 and len(cache) == 1
    assert again._origin is first._origin
    other = (verts * 1.25, faces.clone())  # other content, new tensors: hashed, a new entry
    _assert_answers_for(cache.get(other), other)
    assert hashes[0] == 3 and len(cache) == 2


def test_an_evicted_entry_is_hashed_and_built_again(hashes):
    verts, faces = _sphere()
    small = _sphere(1)
    cache = IndexCache(max_entries=1)
    cache.get((verts, faces))
    cache.get(small)  # evicts the first entry (and its remembered key)
    _assert_answers_for(cache.get((verts, faces)), (verts, faces))
    assert hashes[0] == 3 and len(cache) == 1
    cache.get((verts, faces))
    assert hashes[0] == 3


def test_a_remembered_key_whose_entry_was_evicted_is_hashed_again(hashes):
    verts, faces = _sphere()
    cache = IndexCache(max_entries=2)
    cache.get((verts, faces))
    cache._entries.clear()  # the entry gone, the key still remembered (entries and keys are dropped separately)
    _assert_answers_for(cache.get((verts, faces)), (verts, faces))
    assert hashes[0] == 2 and len(cache) == 1


def test_a_batch_given_as_a_list_is_hashed_once(hashes):
    a, b = _sphere(1), _sphere(2)
    b = (b[0] * 2.0, b[1])
    cache = IndexCache()
    for _ in range(3):
        index = cache.get([Mesh(*a), Mesh(*b)])
    assert hashes[0] == 1
    _assert_answers_for(index, [a, b])
    cache.get([b, a])  # another order: another batch
    assert hashes[0] == 2 and len(cache) == 2
    with torch.no_grad():
        b[0].add_(0.1)  # one member changed in place: the batch is hashed again
    _assert_answers_for(cache.get([a, b]), [a, (b[0].clone(), b[1])])
    assert hashes[0] == 3


def test_vertices_that_require_grad_are_hashed_at_every_call(hashes):
    # A trained reference: fused optimizers and `p.data` updates write without counting, so it is never remembered.
    verts, faces = _sphere()
    verts = torch.nn.Parameter(verts)
    cache = IndexCache()
    optimizer = torch.optim.Adam([verts], lr=0.01, fused=True)
    for _ in range(3):
        index = cache.get((verts, faces))
        _assert_answers_for(index, (verts.detach().clone(), faces))
        dists = index.point_mesh_distance(POINTS).dists
        grad = torch.autograd.grad(dists.sum(), verts, retain_graph=True)[0]
        assert grad.abs().sum() > 0  # the gradient reaches the caller's vertices
        optimizer.zero_grad()
        dists.sum().backward()
        version = verts._version
        optimizer.step()
        assert verts._version == version  # the fused step writes without counting (torch 2.13): why it is excluded
    assert hashes[0] == 3


def test_a_tensor_sharing_a_numpy_array_is_hashed_at_every_call(hashes):
    # torch.from_numpy shares the array's memory: a write to the array is no write torch counts. Such storages are
    # not resizable, which is how the cache tells them apart: they are hashed as before, never remembered.
    verts, faces = _sphere()
    array = verts.numpy().copy()
    shared = torch.from_numpy(array)
    mesh = Mesh(shared, faces)
    cache = IndexCache()
    cache.get(mesh)
    array *= 1.5
    assert shared._version == 0  # torch did not see the write
    _assert_answers_for(cache.get(mesh), (torch.tensor(array), faces))
    _assert_answers_for(cache.get((array, faces.numpy())), (torch.tensor(array), faces))  # numpy in: new tensors
    assert hashes[0] == 3


@pytest.mark.parametrize("before", [True, False])
def test_a_tensor_whose_memory_was_handed_to_numpy_is_hashed_at_every_call(hashes, before):
    # t.numpy() (and np.asarray(t)) mark the storage not resizable, whether before or after the first call.
    verts, faces = _sphere()
    verts = verts.clone()
    cache = IndexCache()
    view = verts.numpy() if before else None
    cache.get((verts, faces))
    if view is None:
        view = np.asarray(verts)
    view[:] *= 1.5
    assert verts._version == 0
    _assert_answers_for(cache.get((verts, faces)), (verts.clone(), faces))
    assert hashes[0] == 2


def test_shared_memory_and_inference_tensors_are_hashed_at_every_call(hashes):
    verts, faces = _sphere()
    shared = verts.clone().share_memory_()  # another process may write there
    cache = IndexCache()
    cache.get((shared, faces))
    cache.get((shared, faces))
    with torch.inference_mode():
        frozen = verts.clone()  # an inference tensor: no version counter
    cache.get((frozen, faces))
    with torch.inference_mode():
        frozen.mul_(2.0)
    _assert_answers_for(cache.get((frozen, faces)), (frozen.clone(), faces))
    assert hashes[0] == 4


def test_a_new_tensor_at_a_reused_id_is_hashed(hashes, monkeypatch):
    # A freed tensor's id can be reused by a new one; the cache keeps weak references, so only the very tensor it
    # hashed finds the key. Every id is made equal here, and the second tensor has the first one's counter and
    # memory (a detached alias): everything but the object is the same, and it is hashed.
    monkeypatch.setattr(index_cache, "id", lambda _: 7, raising=False)
    verts, faces = _sphere()
    cache = IndexCache()
    cache.get((verts, faces))
    cache.get((verts.detach(), faces.detach()))
    assert hashes[0] == 2


def test_the_cache_keeps_no_caller_tensor_alive(hashes):
    verts, faces = _sphere()
    alive = weakref.ref(verts)
    cache = IndexCache()
    index = cache.get((verts, faces))
    del index, verts
    gc.collect()
    assert alive() is None


def test_a_copied_or_pickled_cache_remembers_nothing(hashes):
    verts, faces = _sphere()
    cache = IndexCache()
    cache.get((verts, faces))
    for other in (copy.deepcopy(cache), pickle.loads(pickle.dumps(cache))):
        assert len(other) == 0 and len(other._known) == 0
        _assert_answers_for(other.get((verts, faces)), (verts, faces))
        other.get((verts, faces))
    assert hashes[0] == 3


def test_a_write_torch_does_not_count_is_the_documented_blind_spot(hashes):
    # docs/kernels.md: writes through `.data` (of a tensor that does not require grad), a DLPack export or a raw
    # pointer leave the counter and the storage flags as they were; the cache then finds the key of the values
    # before, as the index it handed out does (no StaleIndexError). New tensors (a clone) are hashed and answered.
    verts, faces = _sphere()
    cache = IndexCache()
    before = cache.get((verts, faces))
    verts.data.mul_(1.5)
    assert verts._version == 0
    assert cache.get((verts, faces))._origin is before._origin
    assert hashes[0] == 1
    _assert_answers_for(cache.get((verts.clone(), faces)), (verts.clone(), faces))
    assert hashes[0] == 2


def test_a_hashed_tensor_stays_resizable(hashes):
    # The hash read the bytes through t.numpy(), which marks the storage as shared with numpy: the caller's tensor
    # could no longer be resized ("Trying to resize storage that is not resizable") and, to the memo, looked like
    # memory torch does not own. The bytes are now read in place; the keys are the same (same bytes).
    verts, faces = _sphere()
    cache = IndexCache()
    cache.get((verts, faces))
    assert verts.untyped_storage().resizable() and faces.untyped_storage().resizable()
    verts.resize_(verts.shape[0] + 1, 3)
    assert verts.shape == (faces.max() + 2, 3)


@pytest.mark.parametrize("loss_type", [NearestVertexDistanceLoss, MeshSurfaceDistanceLoss])
def test_a_training_loop_hashes_its_reference_once(hashes, loss_type):
    # The losses detach the reference and ask their IndexCache at every step; a reference given as a Mesh (and its
    # tensors, given as a tuple) is hashed at the first step only. One that requires grad is hashed at every step.
    verts, faces = _sphere(3)
    simplified = _sphere(2)
    moving = (simplified[0].clone().requires_grad_(True), simplified[1])
    loss = loss_type(two_sided=True)
    for reference in (Mesh(verts, faces), (verts, faces)):
        for _ in range(4):
            loss(moving, reference).backward()
    assert hashes[0] == 1  # was 8
    trained = verts.clone().requires_grad_(True)
    for _ in range(3):
        loss(moving, (trained, faces)).backward()
    assert hashes[0] == 4
