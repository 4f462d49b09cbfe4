"""The distance-set functions measured on prebuilt indexes: the same sets, bit for bit, and refused misfits."""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric import IndexCache, MeshIndex
from torchmeshmetric._checks import DTypeError, ShapeError
from torchmeshmetric.metrics import (
    mesh_surface_distance_loss,
    mesh_surface_distance_sets,
    nearest_vertex_distance_sets,
)
from torchmeshmetric.structures import Mesh, as_mesh

SETS = (mesh_surface_distance_sets, nearest_vertex_distance_sets)


def _meshes(items):
    return [as_mesh(m) for m in items]


def _assert_same(a, b):
    assert torch.equal(a.forward, b.forward)
    assert torch.equal(a.forward_lengths, b.forward_lengths)
    assert (a.reverse is None) == (b.reverse is None)
    if a.reverse is not None:
        assert torch.equal(a.reverse, b.reverse)
        assert torch.equal(a.reverse_lengths, b.reverse_lengths)
    assert torch.equal(a.peak, b.peak)


@pytest.mark.parametrize("distance_sets", SETS)
@pytest.mark.parametrize("tree", ["sah", "morton"])
@pytest.mark.parametrize("two_sided", [False, True])
def test_prebuilt_indexes_give_the_sets_bit_for_bit(frames, distance_sets, tree, two_sided):
    simps, refs = frames
    for items in ([0], [1, 3]):  # one item, and a ragged batch
        simp = _meshes([simps[i] for i in items])
        ref = _meshes([refs[i] for i in items])
        plain = distance_sets(simp, ref, two_sided=two_sided)
        indexed = distance_sets(
            simp,
            ref,
            two_sided=two_sided,
            reference_index=MeshIndex(ref, tree=tree),
            simplified_index=MeshIndex(simp, tree=tree),
        )
        _assert_same(indexed, plain)
        assert float(plain.forward.max()) > 0.0  # the noisy copies are off the references: a real comparison


def test_the_index_cache_serves_both_functions_and_both_give_the_plain_sets(frames):
    simps, refs = frames
    cache = IndexCache()
    simp, ref = _meshes(simps[:2]), _meshes(refs[:2])
    for distance_sets in SETS:
        _assert_same(distance_sets(simp, ref, two_sided=True, indexes=cache), distance_sets(simp, ref, two_sided=True))
    # One entry: the batch of references, found again by the second function; the simplified meshes are not cached.
    assert len(cache) == 1
    # A point-set reference has no mesh to index: measured without the cache, same values.
    points = as_mesh(refs[0]).verts
    _assert_same(
        nearest_vertex_distance_sets(simp[0], points, indexes=cache), nearest_vertex_distance_sets(simp[0], points)
    )
    assert len(cache) == 1


@pytest.mark.parametrize("distance_sets", SETS)
def test_gradients_through_prebuilt_indexes(frames, distance_sets):
    simps, refs = frames
    simp_verts, faces = simps[0]

    def grads(detach_reference, indexed):
        x = simp_verts.clone().requires_grad_(True)
        r = as_mesh(refs[0])
        rv = r.verts.clone().requires_grad_(True)
        ref = Mesh(rv, r.faces)
        options = {"reference_index": MeshIndex(ref)} if indexed else {}
        sets = distance_sets((x, faces), ref, detach_reference=detach_reference, **options)
        sets.forward.square().sum().backward()
        return x.grad, rv.grad

    for detach_reference in (True, False):
        x_grad, ref_grad = grads(detach_reference, indexed=True)
        x_plain, ref_plain = grads(detach_reference, indexed=False)
        assert torch.equal(x_grad, x_plain)
        assert float(x_grad.abs().sum()) > 0
        if detach_reference:
            assert ref_grad is None and ref_plain is None
        else:
            assert torch.equal(ref_grad, ref_plain)
            assert float(ref_grad.abs().sum()) > 0


def test_the_loss_takes_a_prebuilt_index(frames):
    simps, refs = frames
    ref = as_mesh(refs[2])
    loss = mesh_surface_distance_loss(simps[2], ref, power=2, reference_index=MeshIndex(ref))
    assert loss.item() == mesh_surface_distance_loss(simps[2], ref, power=2).item() > 0


@pytest.mark.parametrize("distance_sets", SETS)
def test_misfit_indexes_are_refused(frames, distance_sets):
    simps, refs = frames
    simp, ref, other = as_mesh(simps[0]), as_mesh(refs[0]), as_mesh(refs[1])
    with pytest.raises(ShapeError, match=r"reference_index: expected the index of meshes with \[162\] vertices"):
        distance_sets(simp, ref, reference_index=MeshIndex(other))
    with pytest.raises(ShapeError, match=r"reference_index: .*found one of \[162, \d+\]"):
        distance_sets(simp, ref, reference_index=MeshIndex([ref, other]))
    with pytest.raises(ShapeError, match="simplified_index"):
        distance_sets(simp, ref, two_sided=True, simplified_index=MeshIndex(ref))
    with pytest.raises(TypeError, match="simplified_index: expected mesh items"):
        distance_sets(simp.verts, ref, simplified_index=MeshIndex(simp))
    with pytest.raises(TypeError, match="reference_index: expected a MeshIndex or None, found IndexCache"):
        distance_sets(simp, ref, reference_index=IndexCache())
    with pytest.raises(ValueError, match="reference_index: expected an index built with referenced_only=True"):
        distance_sets(simp, ref, reference_index=MeshIndex(ref, referenced_only=False))
    narrower = r"{}: expected an index of dtype torch\.float64 .*found one of dtype torch\.float32.*MeshIndex\(mesh\.to"
    with pytest.raises(DTypeError, match=narrower.format("reference_index")):
        distance_sets(simp, ref, reference_index=MeshIndex(ref.to(dtype=torch.float32)))
    # The reverse direction follows the same rule: float64 reference vertices on a float32 simplified index.
    simp32 = simp.to(dtype=torch.float32)
    with pytest.raises(DTypeError, match=narrower.format("simplified_index")):
        distance_sets(simp32, ref, two_sided=True, simplified_index=MeshIndex(simp32))


def test_nearest_vertex_reference_index_needs_mesh_references(frames):
    simps, refs = frames
    ref = as_mesh(refs[0])
    with pytest.raises(TypeError, match="reference_index: expected mesh items"):
        nearest_vertex_distance_sets(simps[0], ref.verts, reference_index=MeshIndex(ref))


def test_sampled_surface_mode_refuses_an_index(frames):
    simps, refs = frames
    with pytest.raises(ValueError, match="only with surface_samples=None"):
        mesh_surface_distance_sets(simps[0], refs[0], surface_samples=100, reference_index=MeshIndex(refs[0]))


@pytest.mark.parametrize("distance_sets", SETS)
def test_a_wider_index_measures_narrower_points(distance_sets):
    sphere = trimesh.creation.icosphere(subdivisions=2)
    points = torch.tensor([[0.0, 0.0, 2.0]])  # float32
    index = MeshIndex(sphere)  # float64
    sets = distance_sets(points, sphere, reference_index=index)
    assert sets.forward.dtype == torch.float64
    assert torch.equal(sets.forward, distance_sets(points, sphere).forward)


@pytest.mark.parametrize("distance_sets", SETS)
def test_indexes_in_the_promoted_dtype_answer_both_directions_of_a_mixed_pair(frames, distance_sets):
    """float32 simplified, float64 reference: indexes built in float64 (the promoted dtype) serve both directions."""
    simps, refs = frames
    simp, ref = as_mesh(simps[0]).to(dtype=torch.float32), as_mesh(refs[0])
    options = {"reference_index": MeshIndex(ref), "simplified_index": MeshIndex(simp.to(dtype=torch.float64))}
    indexed = distance_sets(simp, ref, two_sided=True, **options)
    plain = distance_sets(simp, ref, two_sided=True)
    assert indexed.forward.dtype == indexed.reverse.dtype == torch.float64
    assert torch.equal(indexed.forward, plain.forward) and torch.equal(indexed.reverse, plain.reverse)


@pytest.mark.parametrize("distance_sets", SETS)
def test_gradients_reach_the_given_meshes_not_the_tensors_an_index_was_built_from(frames, distance_sets):
    simps, refs = frames
    simp_verts, faces = simps[1]
    ref = as_mesh(refs[1])

    def grads(indexed):
        x = simp_verts.clone().requires_grad_(True)
        rv = ref.verts.clone().requires_grad_(True)
        options = {}
        if indexed:  # indexes built from other tensors of equal values, without autograd
            options = {"reference_index": MeshIndex(ref), "simplified_index": MeshIndex((simp_verts.clone(), faces))}
        sets = distance_sets((x, faces), Mesh(rv, ref.faces), two_sided=True, detach_reference=False, **options)
        (sets.forward.square().sum() + sets.reverse.square().sum()).backward()
        return x.grad, rv.grad

    for got, expected in zip(grads(indexed=True), grads(indexed=False), strict=True):
        assert torch.equal(got, expected)
        assert float(got.abs().sum()) > 0
