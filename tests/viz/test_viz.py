import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import Mesh, ShapeError
from torchmeshmetric.viz import error_colors, write_error_ply


def test_error_colors_endpoints_monotone_and_clamped():
    c = error_colors(torch.tensor([0.0, 0.5, 1.0, 7.0]), vmax=1.0)
    assert c.dtype == torch.uint8 and c.shape == (4, 4)
    assert c[0].tolist() == [68, 1, 84, 255] and c[2].tolist() == c[3].tolist() == [253, 231, 37, 255]
    # brightness grows with the error along the scale
    d = torch.linspace(0, 1, 50)
    lum = error_colors(d, vmax=1.0)[:, :3].double() @ torch.tensor([0.2126, 0.7152, 0.0722], dtype=torch.float64)
    assert bool((lum[1:] >= lum[:-1] - 1e-9).all())


def test_error_colors_default_vmax_and_shape_check():
    d = torch.arange(100, dtype=torch.float64)
    c = error_colors(d)  # vmax = 95th percentile
    assert c[-1].tolist() == c[-2].tolist() == [253, 231, 37, 255]
    with pytest.raises(ShapeError):
        error_colors(torch.zeros(3, 1))


def test_write_error_ply_round_trip(tmp_path):
    m = trimesh.creation.icosphere(subdivisions=1)
    mesh = Mesh(torch.tensor(m.vertices), torch.tensor(m.faces))
    d = torch.linspace(0, 1, mesh.num_verts, dtype=torch.float64)
    path = write_error_ply(tmp_path / "e.ply", mesh, d, vmax=1.0)
    back = trimesh.load(path, process=False)
    np.testing.assert_allclose(back.vertices, m.vertices, atol=1e-6)
    assert np.array_equal(back.visual.vertex_colors, error_colors(d, vmax=1.0).numpy())
    with pytest.raises(FileExistsError):
        write_error_ply(path, mesh, d)
    with pytest.raises(ShapeError, match="dists"):
        write_error_ply(tmp_path / "f.ply", mesh, d[:-2])


def test_write_error_ply_accepts_the_vertex_set(tmp_path):
    # an unreferenced vertex (index 3): distances of the paper's vertex set have 3 values
    mesh = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [9, 9, 9]]), torch.tensor([[0, 1, 2]]))
    path = write_error_ply(tmp_path / "e.ply", mesh, torch.tensor([0.0, 0.5, 1.0]), vmax=1.0)
    assert len(trimesh.load(path, process=False).vertices) == 3
