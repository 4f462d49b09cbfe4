"""simplify_tracking and TemporalSlide check what they are given, naming their own arguments (issue 41, theme 5)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from torchmeshmetric._checks import DTypeError, EmptyInputError
from torchmeshmetric.simplification import TemporalSlide, simplify_tracking
from torchmeshmetric.structures import Mesh

V = torch.tensor([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=torch.float64)
F = torch.tensor([[0, 1, 2], [0, 2, 3]])


def test_simplify_tracking_of_no_frames():
    with pytest.raises(EmptyInputError, match=r"^frames: expected at least one frame, found none"):
        simplify_tracking([], 0.5, [])


@pytest.mark.parametrize("hidden", [-1, 0, 2.5, True])
def test_temporal_slide_hidden_width(hidden):
    with pytest.raises(ValueError, match=f"^hidden: expected an int >= 1 .*found {hidden!r}"):
        TemporalSlide(hidden=hidden)


def test_temporal_slide_takes_numpy_width_and_names_its_meshes():
    torch.manual_seed(0)
    slide = TemporalSlide(hidden=np.int64(4)).double()
    mesh = Mesh(V, F)
    assert slide(mesh, (V + 0.01, F)).shape == (4, 3)
    with pytest.raises(EmptyInputError, match=r"^warped_previous: expected a mesh with faces"):
        slide(mesh, (V, torch.zeros(0, 3, dtype=torch.long)))
    with pytest.raises(DTypeError, match=r"^warped_previous: expected simplified_k's dtype torch.float64"):
        slide(mesh, (V.float(), F))
    with pytest.raises(TypeError, match=r"^simplified_k: expected a Mesh"):
        slide("mesh", mesh)
    with pytest.raises(ValueError, match=r"^warped_previous.faces: expected vertex indices in \[0, 3\]"):
        slide(mesh, (V, F + 2))


def test_registered_qem_names_its_arguments():
    # max_distance="1" gave Python's bare "'>' not supported between instances of 'str' and 'int'"; a scalar tensor
    # weight was refused while simplify_anchored_qem takes it (found by review).
    import trimesh

    from torchmeshmetric.simplification import simplify_registered_qem

    sphere = trimesh.creation.icosphere(subdivisions=2)
    for key, value in (("max_distance", "1"), ("candidate_fraction", "0.5")):
        with pytest.raises(TypeError, match=rf"{key}: expected a float, found str"):
            simplify_registered_qem(sphere, sphere, 0.5, **{key: value})
    assert simplify_registered_qem(sphere, sphere, 0.5, weight=torch.tensor(1.0)).num_faces == 160
