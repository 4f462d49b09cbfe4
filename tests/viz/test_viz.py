import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import Mesh, NonFiniteError, ShapeError
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


BAD_VMAX = [
    (0.0, ValueError, "vmax: expected a distance > 0"),
    (-1.0, ValueError, "vmax: expected a distance > 0"),
    (float("nan"), NonFiniteError, "vmax: expected a finite distance"),
    (float("inf"), NonFiniteError, "vmax: expected a finite distance"),
    ("x", TypeError, "vmax: expected None or a positive number, found str 'x'"),
    (True, TypeError, "vmax: expected None or a positive number, found bool"),
]


@pytest.mark.parametrize(("vmax", "error", "message"), BAD_VMAX)
def test_error_colors_refuse_a_vmax_that_is_not_a_finite_positive_number(vmax, error, message):
    # 0, -1, NaN and inf made every vertex the colour of "no error" (review A, finding 3)
    with pytest.raises(error, match=message):
        error_colors(torch.linspace(0, 1, 5), vmax=vmax)


@pytest.mark.parametrize("vmax", [None, 1.0])
def test_error_colors_refuse_nan_and_negative_distances(vmax, tmp_path):
    # a NaN gave an IndexError with vmax=1 and an all-dark (no error) map with the default vmax (review A, 3)
    with pytest.raises(NonFiniteError, match=r"dists: expected finite values, found 1 NaN/Inf"):
        error_colors(torch.tensor([float("nan"), 0.5]), vmax)
    with pytest.raises(ValueError, match=r"dists: expected distances >= 0, found 2 negative value\(s\), the least -1"):
        error_colors(torch.tensor([0.5, -0.5, -1.0]), vmax)
    m = trimesh.creation.icosphere(subdivisions=1)
    with pytest.raises(NonFiniteError, match="dists"):
        write_error_ply(tmp_path / "e.ply", m, torch.full((len(m.vertices),), float("nan")), vmax=vmax)
    assert list(tmp_path.iterdir()) == []


def test_default_vmax_is_the_largest_error_when_the_95th_percentile_is_zero():
    # 96 vertices on the surface and 4 off it: the 95th percentile is 0, which coloured all of them "no error"
    d = torch.cat([torch.zeros(96), torch.tensor([0.1, 0.2, 0.3, 0.4])])
    c = error_colors(d)
    assert c[-1].tolist() == [253, 231, 37, 255] and c[0].tolist() == [68, 1, 84, 255]
    assert c[-4].tolist() == error_colors(torch.tensor([0.1]), vmax=0.4)[0].tolist()
    assert error_colors(torch.zeros(3)).tolist() == [[68, 1, 84, 255]] * 3  # no error at all: all dark
