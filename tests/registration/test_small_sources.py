"""Registration of tiny sources (3 vertices) is robust in float32 and float64: no singular solve, no NaN, no raw
torch message on the command line."""

import warnings

import numpy as np
import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric import Mesh, RegistrationWarning, register_rigid
from torchmeshmetric.cli import main
from torchmeshmetric.evaluation import default_register

SPHERE = trimesh.creation.icosphere(subdivisions=1)
TRIANGLE = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
MODES = [
    {"point_to_plane": True},
    {"point_to_plane": False},
    {"point_to_plane": True, "scale": True},
    {"point_to_plane": False, "scale": True},
]


def _tiny(seed: int, n_verts: int, dtype) -> Mesh:
    rng = np.random.default_rng(seed)
    verts = rng.normal(size=(n_verts, 3)) * 0.5
    faces = [[0, 1, 2]] + [[0, i - 1, i] for i in range(3, n_verts)]
    return Mesh(torch.tensor(verts, dtype=dtype), torch.tensor(faces))


def _sphere(dtype) -> Mesh:
    return Mesh(torch.tensor(SPHERE.vertices, dtype=dtype), torch.tensor(SPHERE.faces))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n_verts=st.integers(3, 5), mode=st.sampled_from(MODES))
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("direction", ["tiny->sphere", "sphere->tiny", "tiny->tiny"])
def test_rigid_registration_of_tiny_meshes_is_finite(dtype, direction, seed, n_verts, mode):
    tiny, other = _tiny(seed, n_verts, dtype), _tiny(seed + 1, 3, dtype)
    src, dst = {
        "tiny->sphere": (tiny, _sphere(dtype)),
        "sphere->tiny": (_sphere(dtype), tiny),
        "tiny->tiny": (tiny, other),
    }[direction]
    r = register_rigid(src, dst, **mode)
    assert r.verts.dtype == dtype
    for name in ("rotation", "translation", "scale", "verts", "rmse"):
        assert torch.isfinite(getattr(r, name)).all(), name
    torch.testing.assert_close(r.rotation @ r.rotation.T, torch.eye(3, dtype=dtype), atol=1e-4, rtol=0)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_a_3_vertex_triangle_registers_exactly_onto_its_translated_copy(dtype):
    src = TRIANGLE.to(dtype=dtype)
    dst = Mesh(src.verts + torch.tensor([0.0, 0.0, 0.1], dtype=dtype), src.faces)
    for mode in MODES:
        r = register_rigid(src, dst, **mode)
        assert float(r.rmse) <= 10 * torch.finfo(dtype).eps, mode


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("direction", ["tiny->sphere", "sphere->tiny"])
def test_default_registration_of_a_3_vertex_mesh_is_finite(dtype, direction):
    tiny = TRIANGLE.to(dtype=dtype)
    src, dst = (tiny, _sphere(dtype)) if direction == "tiny->sphere" else (_sphere(dtype), tiny)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RegistrationWarning)  # an implausible fit is reported, not an error
        r = default_register(src, dst)
    assert torch.isfinite(r.verts).all() and torch.isfinite(r.residual).all()


@pytest.mark.parametrize("direction", ["tiny->sphere", "sphere->tiny"])
def test_cli_register_of_a_3_vertex_mesh_prints_no_raw_torch_message(capsys, tmp_path, direction):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    SPHERE.export(tmp_path / "sphere.ply")
    src, dst = ("tri.obj", "sphere.ply") if direction == "tiny->sphere" else ("sphere.ply", "tri.obj")
    args = ["register", "--source", str(tmp_path / src), "--target", str(tmp_path / dst)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RegistrationWarning)
        code = main([*args, "--out", str(tmp_path / "out.ply")])
    _, err = capsys.readouterr()
    assert code in (0, 3), err
    assert "torch" not in err and "singular" not in err and "NaN" not in err
