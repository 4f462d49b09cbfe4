"""Every public entry point checks what it is given: a typed error naming the argument, or the same result for the
other accepted forms (issue 41, theme 5)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from torchmeshmetric._checks import (
    DeviceError,
    DTypeError,
    IndexRangeError,
    NonFiniteError,
    ShapeError,
)
from torchmeshmetric.mpeg.comparison.equality import EqualityModel, mesh_equality
from torchmeshmetric.mpeg.comparison.tfan_comparison import tfan_equality
from torchmeshmetric.mpeg.comparison.topology import topology_equivalence
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.mpeg.sampling.edge_sampling import edge_sample
from torchmeshmetric.mpeg.sampling.face_sampling import face_sample
from torchmeshmetric.mpeg.sampling.prnd_sampling import prnd_sample
from torchmeshmetric.mpeg.sampling.subdivision_sampling import subdivision_sample
from torchmeshmetric.structures import Mesh, as_mesh

V = torch.tensor([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
F = torch.tensor([[0, 1, 2], [0, 2, 3]])


@pytest.mark.parametrize("kind", ["face", "vertex"])
@pytest.mark.parametrize("bad", [np.array([1.0, 0.4]), np.array([True, False]), torch.tensor([1.0, 0.0])])
def test_topology_maps_must_be_integers(kind, bad):
    a, b = (V, F), (V, F[[1, 0]])
    fmap, vmap = torch.tensor([1, 0]), torch.arange(4)
    maps = {"face": (bad, vmap), "vertex": (fmap, np.resize(bad, 4))}[kind]
    with pytest.raises(DTypeError, match=f"^{kind}_map: expected an integer array of indices, found dtype"):
        topology_equivalence(a, b, *maps)
    assert topology_equivalence(a, b, fmap, vmap).matching  # the integer maps still match


def test_mesh_equality_compares_models_without_triangles_and_takes_any_mesh_form():
    """Models without triangles were refused (EmptyInputError); mm compares them as point clouds."""
    empty = (torch.tensor([[0.0, 0, 0], [1, 0, 0]]), torch.zeros(0, 3, dtype=torch.long))
    other = (torch.tensor([[5.0, 0, 0], [1, 7, 0]]), torch.zeros(0, 3, dtype=torch.long))
    assert mesh_equality(empty, other).report() == "model vertices are not equals"
    assert mesh_equality(empty, (empty[0].flip(0), empty[1])).report() == "model vertices are equals"
    assert mesh_equality((V, F), other).report() == "meshes are not equal, number of triangles are different 2 vs 0"
    assert mesh_equality((V, F), Mesh(V, F[[1, 0]])).equal
    assert mesh_equality(TexturedMesh(Mesh(V, F)), (V, F)).equal


@pytest.mark.parametrize(
    ("triangles", "error", "message"),
    [
        (
            np.array([[0, 1, 9]]),
            IndexRangeError,
            r"EqualityModel.triangles: expected indices of positions in \[0, 3\], found values in \[0, 9\]",
        ),
        (
            np.array([[0, 1, -1]]),
            IndexRangeError,
            r"EqualityModel.triangles: expected indices of positions in \[0, 3\], found values in \[-1, 1\]",
        ),
        (
            np.array([[0.0, 1.0, 2.0]]),
            DTypeError,
            "EqualityModel.triangles: expected integer indices, found dtype float64",
        ),
        (np.array([0, 1, 2]), ShapeError, r"EqualityModel.triangles: expected shape \(N, 3\), found \(3,\)"),
    ],
)
def test_equality_model_tables_are_checked_when_built(triangles, error, message):
    with pytest.raises(error, match=f"^{message}"):
        EqualityModel(V.numpy(), triangles)


def test_equality_model_other_tables_and_tfan_forms():
    with pytest.raises(NonFiniteError, match=r"^EqualityModel.positions: expected finite values"):
        EqualityModel(np.array([[0.0, 0, np.nan], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    with pytest.raises(IndexRangeError, match=r"^EqualityModel.triangles_uv: expected indices of uvs in \[0, 0\]"):
        EqualityModel(V.numpy(), F.numpy(), uvs=np.zeros((1, 2)), triangles_uv=np.array([[0, 0, 0], [0, 0, 3]]))
    a = EqualityModel(V.numpy(), F.numpy())
    assert tfan_equality(a, EqualityModel(V.numpy(), torch.tensor([[0, 1, 2], [0, 2, 3]]))).equal
    assert tfan_equality(a, (V, F)).equal and tfan_equality(Mesh(V, F), TexturedMesh(Mesh(V, F))).equal


@pytest.mark.parametrize(
    ("field", "value", "error", "message"),
    [
        ("uvs", torch.zeros(3, 3, 2), ShapeError, r"uvs: expected shape \(2, 3, 2\), found \(3, 3, 2\)"),
        ("uvs", torch.full((2, 3, 2), float("nan")), NonFiniteError, "uvs: expected finite values"),
        ("colors", torch.zeros(7, 3), ShapeError, r"colors: expected shape \(4, 3\), found \(7, 3\)"),
        ("texture", np.full((2, 2, 3), 1000.0), DTypeError, "texture: expected an .* uint8 numpy image"),
        ("texture", np.zeros((2, 2), np.uint8), ShapeError, r"texture: expected shape \(H, W, 3\)"),
    ],
)
def test_textured_mesh_is_checked_when_built(field, value, error, message):
    with pytest.raises(error, match=f"^{message}"):
        TexturedMesh(Mesh(V, F), **{field: value})


@pytest.mark.parametrize(
    "sample",
    [
        lambda m: face_sample(m, resolution=8),
        lambda m: prnd_sample(m, num_samples=30),
        lambda m: edge_sample(m, resolution=8),
        lambda m: subdivision_sample(m, area_threshold=0.05),
    ],
    ids=["face", "prnd", "ediv", "sdiv"],
)
def test_samplers_take_a_mesh_or_a_tuple(sample):
    want = sample(TexturedMesh(Mesh(V, F))).points
    assert torch.equal(sample(Mesh(V, F)).points, want)
    assert torch.equal(sample((V, F)).points, want)
    with pytest.raises(TypeError, match=r"^mesh: expected a Mesh, a \(verts, faces\) tuple"):
        sample("not a mesh")


def test_device_strings_are_checked():
    with pytest.raises(DeviceError, match=r"^device: 'bogus' is not a device"):
        as_mesh((V, F), device="bogus")
    if not torch.cuda.is_available():
        with pytest.raises(DeviceError, match=r"^device: 'cuda' asked, but no CUDA device is available here"):
            as_mesh((V, F), device="cuda")
    from torchmeshmetric.registration import register_nonrigid

    with pytest.raises(DeviceError, match=r"^device: 'bogus' is not a device"):
        register_nonrigid((V, F), (V, F), device="bogus")
