"""The shared input checks: the fast finiteness test agrees with the elementwise one; numpy arrays and dtypes named."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

import torchmeshmetric as tmm
from torchmeshmetric._checks import DTypeError, NonFiniteError, all_finite, check_finite
from torchmeshmetric.stats import distance_statistics


@pytest.mark.parametrize("dtype", [torch.float16, torch.float32, torch.float64])
def test_all_finite_agrees_with_isfinite(dtype: torch.dtype) -> None:
    big = torch.finfo(dtype).max
    cases = [
        torch.tensor([1.0, -2.0, 0.0]),
        torch.tensor([big, big, big]),  # finite values whose sum overflows: still finite
        torch.tensor([-big, -big]),
        torch.tensor([1.0, float("nan")]),
        torch.tensor([float("inf"), 1.0]),
        torch.tensor([float("inf"), -float("inf")]),  # the sum is NaN
        torch.tensor([-float("inf")]),
    ]
    for x in cases:
        x = x.to(dtype)
        assert all_finite(x) == bool(torch.isfinite(x).all()), x


def test_all_finite_does_not_record_gradients() -> None:
    x = torch.ones(4, 3, requires_grad=True)
    assert all_finite(x)
    assert x.grad is None


def test_check_finite_counts_the_bad_values() -> None:
    x = torch.tensor([[1.0, float("nan"), float("inf")], [3e38, 3e38, 3e38]])
    with pytest.raises(NonFiniteError, match="points: expected finite values, found 2 NaN/Inf"):
        check_finite(x, "points")
    check_finite(x[1:], "points")  # an overflowing sum of finite values is accepted


def _sphere() -> tuple[np.ndarray, np.ndarray]:
    s = trimesh.creation.icosphere(subdivisions=1)
    return np.asarray(s.vertices), np.asarray(s.faces)


def _numpy_cases() -> dict[str, tuple[object, str]]:
    v, f = _sphere()
    vt, ft, p = torch.as_tensor(v), torch.as_tensor(f), np.zeros((5, 3))
    return {
        "point_mesh_distance": (lambda: tmm.point_mesh_distance(p, vt, ft), "points"),
        "nearest_vertex_distance": (lambda: tmm.nearest_vertex_distance(p, vt), "points"),
        "ref_points": (lambda: tmm.nearest_vertex_distance(torch.zeros(5, 3, dtype=torch.float64), v), "ref_points"),
        "MeshIndex query": (lambda: tmm.MeshIndex(vt, ft).point_mesh_distance(p), "points"),
        "numpy verts": (lambda: tmm.point_mesh_distance(torch.as_tensor(p), v, ft), "verts"),
        "sample_surface verts": (lambda: tmm.sample_surface(v, ft, 10), "verts"),
        "numpy faces": (lambda: tmm.point_mesh_distance(torch.as_tensor(p), vt, f), "faces"),
        "distance_statistics": (lambda: distance_statistics(np.array([1.0, 2.0])), "dists"),
        "closest_point_on_triangle": (
            lambda: tmm.closest_point_on_triangle(np.zeros(3), vt[0], vt[1], vt[2]),
            "points",
        ),
    }


@pytest.mark.parametrize("case", list(_numpy_cases()))
def test_a_numpy_array_for_a_tensor_is_named(case: str) -> None:
    # A numpy array was iterated as a list of point sets: "ShapeError: points[0]: expected shape (P, 3), found (3)";
    # numpy verts with faces said "faces: only valid when verts is a tensor".
    call, name = _numpy_cases()[case]
    with pytest.raises(
        TypeError, match=rf"^{name}: expected .*, found numpy\.ndarray; convert it with torch\.as_tensor\({name}\)$"
    ):
        call()


def test_numpy_items_of_a_list_still_convert() -> None:
    v, f = _sphere()
    p = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    got = tmm.point_mesh_distance([p], torch.as_tensor(v), torch.as_tensor(f)).dists
    want = tmm.point_mesh_distance(torch.as_tensor(p), torch.as_tensor(v), torch.as_tensor(f)).dists
    # The centre is inside the unit icosphere, below its faces; (0, 0, 2) is 1 above its pole vertex.
    assert torch.equal(got, want) and 0.85 < float(want[0]) < 1.0 and abs(float(want[1]) - 1.0) < 1e-12


@pytest.mark.parametrize(
    ("dtype", "advice"),
    [
        (torch.int64, "convert integer coordinates with .float"),
        (torch.bool, "convert boolean coordinates with .float"),
        (torch.complex64, "complex coordinates have no distance here"),
    ],
)
def test_the_dtype_advice_names_what_was_found(dtype: torch.dtype, advice: str) -> None:
    v, f = _sphere()
    with pytest.raises(DTypeError, match=rf"points: .*found dtype {dtype}; {advice}"):
        tmm.point_mesh_distance(torch.zeros(5, 3, dtype=dtype), torch.as_tensor(v), torch.as_tensor(f))
