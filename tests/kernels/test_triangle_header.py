"""triangle.h's squared point-triangle distance equals the torch kernel's bit for bit, on every (point, face) pair.

The production extension only exposes selections; this test compiles a test-only extension around the same header
(``tri_sq_dist``), so the all-pairs hook stays out of the library.
"""

from __future__ import annotations

import pytest
import torch

from torchmeshmetric import native
from torchmeshmetric.kernels.triangle import region_candidates

_SOURCE = r"""
#include <torch/extension.h>
#include "triangle.h"

template <typename T>
torch::Tensor pair_impl(const torch::Tensor& points, const torch::Tensor& verts, const torch::Tensor& faces) {
  const int64_t F = faces.size(0), P = points.size(0);
  const T* V = verts.data_ptr<T>();
  const int64_t* Fi = faces.data_ptr<int64_t>();
  const T* Pp = points.data_ptr<T>();
  auto out = torch::empty({P, F}, points.options());
  T* o = out.data_ptr<T>();
  for (int64_t f = 0; f < F; ++f) {
    const auto d = tmm::face_data(V + 3 * Fi[3 * f], V + 3 * Fi[3 * f + 1], V + 3 * Fi[3 * f + 2]);
    for (int64_t i = 0; i < P; ++i) o[i * F + f] = tmm::tri_sq_dist(d, Pp + 3 * i);
  }
  return out;
}

torch::Tensor pair_sq_dists(torch::Tensor points, torch::Tensor verts, torch::Tensor faces) {
  if (points.scalar_type() == torch::kFloat64) return pair_impl<double>(points, verts, faces);
  return pair_impl<float>(points, verts, faces);
}
"""


@pytest.fixture(scope="module")
def pair_sq_dists():  # type: ignore[no-untyped-def]
    if native.try_load("bvh") is None:
        pytest.skip("no C++ compiler: the extension cannot be built")
    from torch.utils.cpp_extension import load_inline

    module = load_inline(
        name="tmm_triangle_header_test",
        cpp_sources=[_SOURCE],
        functions=["pair_sq_dists"],
        extra_cflags=list(native.EXTENSIONS["bvh"].cflags),
        extra_include_paths=[str(native.HOME)],
    )
    return module.pair_sq_dists


def _sq_to_faces(points: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    tri = verts[faces]
    p = points[:, None]
    return region_candidates(
        p - tri[:, 0], p - tri[:, 1], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]
    )[-1].amin(-1)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_tri_sq_dist_is_bit_identical_to_torch(pair_sq_dists, dtype: torch.dtype) -> None:  # type: ignore[no-untyped-def]
    g = torch.Generator().manual_seed(2)
    verts = torch.randn(100, 3, generator=g, dtype=dtype)
    faces = torch.randint(0, 100, (200, 3), generator=g)
    faces[:30, 2] = faces[:30, 1]  # zero-area faces
    points = torch.randn(300, 3, generator=g, dtype=dtype)
    points[:40] = verts[faces[:40, 0]]  # points on vertices
    want = _sq_to_faces(points, verts, faces)
    assert torch.equal(pair_sq_dists(points, verts, faces), want)
