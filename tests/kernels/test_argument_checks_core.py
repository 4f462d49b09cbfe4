"""Review D, findings 10-11: closest_point_on_triangle's inputs and max_memory, checked alike everywhere."""

from __future__ import annotations

import pytest
import torch

from torchmeshmetric import (
    MeshIndex,
    NonFiniteError,
    ShapeError,
    closest_point_on_triangle,
    nearest_vertex_distance,
    point_mesh_distance,
)

A, B, C = torch.tensor([0.0, 0, 0]), torch.tensor([1.0, 0, 0]), torch.tensor([0.0, 1, 0])


def test_closest_point_on_triangle_refuses_nan_and_bad_shapes_naming_the_argument():
    # NaN gave a NaN answer; 2-D coordinates "not enough values to unpack (expected 3, got 2)".
    with pytest.raises(NonFiniteError, match=r"^points"):
        closest_point_on_triangle(torch.tensor([float("nan"), 0, 0]), A, B, C)
    with pytest.raises(NonFiniteError, match=r"^c"):
        closest_point_on_triangle(A, A, B, torch.tensor([0.0, float("inf"), 0]))
    with pytest.raises(ShapeError, match=r"a: expected shape \(\.\.\., 3\), found \(2\)"):
        closest_point_on_triangle(torch.tensor([0.0, 0, 0]), A[:2], B, C)
    with pytest.raises(ShapeError, match=r"expected shapes that broadcast"):
        closest_point_on_triangle(torch.zeros(4, 3), torch.zeros(5, 3), B, C)
    with pytest.raises(TypeError, match=r"b: expected a tensor"):
        closest_point_on_triangle(A, A, [1.0, 0, 0], C)  # type: ignore[arg-type]
    assert closest_point_on_triangle(torch.tensor([0.25, 0.25, 2.0]), A, B, C).sq_dists.item() == 4.0


@pytest.mark.parametrize("backend", ["auto", "bruteforce", "pruned", "bvh"])
@pytest.mark.parametrize(("max_memory", "error"), [(0, ValueError), (-1, ValueError), (1.5, TypeError)])
def test_max_memory_is_checked_by_every_backend_alike(backend, max_memory, error):
    # Only the brute force refused 0; -1 and 1.5 were accepted by "auto" (bvh) and "pruned".
    v, f, p = torch.stack([A, B, C]), torch.tensor([[0, 1, 2]]), torch.tensor([[0.0, 0, 1]])
    with pytest.raises(error, match=r"max_memory: expected an int"):
        point_mesh_distance(p, v, f, backend=backend, max_memory=max_memory)
    with pytest.raises(error, match=r"max_memory: expected an int"):
        nearest_vertex_distance(p, v, backend=backend, max_memory=max_memory)
    with pytest.raises(error, match=r"max_memory: expected an int"):
        MeshIndex(v, f, backend=backend, max_memory=max_memory)
