import numpy as np
import pytest
import torch

from torchmeshmetric import point_mesh_distance
from torchmeshmetric.data import add_capture_defects, demo_sequence


@pytest.fixture(scope="module")
def clean():
    return demo_sequence(1, resolution=32).frames[0]


def _analyse(m):
    v = m.verts.double().numpy()
    f = m.faces.numpy()
    _, inv, counts = np.unique(v, axis=0, return_inverse=True, return_counts=True)
    coincident = counts[inv.reshape(-1)] > 1
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    tri = v[f]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    edge_len = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)
    zero_edge = ~repeated & (edge_len == 0).any(1)
    collinear = ~repeated & ~zero_edge & (area2 <= 1e-12)
    unreferenced = np.setdiff1d(np.arange(v.shape[0]), f.reshape(-1)).size
    return dict(
        duplicates=int(coincident.sum()),
        zero_edge=int(zero_edge.sum()),
        collinear=int(collinear.sum()),
        repeated=int(repeated.sum()),
        unreferenced=unreferenced,
    )


def test_each_defect_is_present(clean):
    base = _analyse(clean)
    assert base == dict(duplicates=0, zero_edge=0, collinear=0, repeated=0, unreferenced=0)
    noisy = add_capture_defects(
        clean.to(dtype=torch.float64),
        seed=3,
        num_zero_length_edges=7,
        num_collinear_faces=5,
        num_repeated_index_faces=4,
        num_unreferenced=9,
    )
    got = _analyse(noisy)
    assert got["zero_edge"] == 7
    assert got["collinear"] == 5
    assert got["repeated"] == 4
    assert got["unreferenced"] == 9
    assert got["duplicates"] >= 2 * round(0.02 * clean.num_verts)
    assert noisy.num_faces == clean.num_faces + 7 + 5 + 4
    assert float(noisy.verts.abs().max()) == 1.0  # normalised to +-1


def test_surface_unchanged_up_to_normalisation(clean):
    noisy = add_capture_defects(clean, seed=0, shuffle=False, normalize=False)
    d = point_mesh_distance(noisy.verts[: clean.num_verts].double(), clean.to(dtype=torch.float64)).dists
    assert float(d.max()) == 0.0
    assert torch.equal(noisy.verts[: clean.num_verts], clean.verts)
    # the added (zero-area) faces lie on the clean surface
    tri = noisy.verts[noisy.faces[clean.num_faces :]].reshape(-1, 3).double()
    assert float(point_mesh_distance(tri, clean.to(dtype=torch.float64)).dists.max()) < 1e-6


def test_deterministic_and_seeded(clean):
    a = add_capture_defects(clean, seed=1)
    b = add_capture_defects(clean, seed=1)
    c = add_capture_defects(clean, seed=2)
    assert torch.equal(a.verts, b.verts) and torch.equal(a.faces, b.faces)
    assert not torch.equal(a.faces, c.faces)


def test_bad_arguments(clean):
    with pytest.raises(ValueError, match="num_unreferenced"):
        add_capture_defects(clean, num_unreferenced=-1)
    with pytest.raises(ValueError, match="duplicate_fraction"):
        add_capture_defects(clean, duplicate_fraction=1.5)
