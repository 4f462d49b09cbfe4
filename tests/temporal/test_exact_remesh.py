"""The registered forms under the validation's exact remesh (tests/benchmarks/temporal_validation.py, issue 44's
follow-up): every frame split 1-to-3 at random interior points, so the surface is kept exactly and only the
connectivity differs, with the true correspondence as the registration (no tracking drift)."""

from __future__ import annotations

import functools

import numpy as np
import torch

from tests.benchmarks.temporal_validation import distort, remesh_exact
from tests.temporal.test_registered import _performer
from torchmeshmetric.kernels import MeshIndex
from torchmeshmetric.registration.cache import CachedRegistration
from torchmeshmetric.structures import Mesh
from torchmeshmetric.temporal import RegisteredPair, kg_error, registered_pair, sted


def _true_registrations(a: torch.Tensor, faces: torch.Tensor, frames: list[Mesh]) -> list[CachedRegistration]:
    """Each remeshed vertex of frame k-1 moved to its barycentric place on the original frame k."""
    out = []
    for k in range(len(frames) - 1):
        hit = MeshIndex(Mesh(a[k], faces)).point_mesh_distance(frames[k].verts)
        moved = (hit.bary.double()[..., None] * a[k + 1][faces[hit.face_idx]]).sum(1)
        out.append(CachedRegistration(moved, torch.zeros(frames[k].num_verts), True, 0.0))
    return out


@functools.cache
def _case(kind: str, level: float) -> tuple[torch.Tensor, torch.Tensor, RegisteredPair]:
    a, faces = _performer()
    rng = np.random.default_rng(0)
    original = [remesh_exact(v, faces, rng) for v in a]
    diag = float(Mesh(a[0], faces).bbox_diagonal())
    b = a.clone() if kind == "none" else distort(kind, level, a, faces, diag, seed=7)
    distorted = [remesh_exact(v, faces, rng) for v in b]
    return a, b, registered_pair(original, distorted, registrations=_true_registrations(a, faces, original))


def test_exact_remesh_keeps_the_surface() -> None:
    a, faces = _performer()
    mesh = remesh_exact(a[0], faces, np.random.default_rng(0))
    assert torch.equal(mesh.verts[: a.shape[1]], a[0])  # no vertex moves
    assert float(MeshIndex(Mesh(a[0], faces)).point_mesh_distance(mesh.verts).dists.max()) < 1e-12
    area = Mesh(a[0], faces).face_areas().sum()
    assert abs(float(mesh.face_areas().sum() / area) - 1) < 1e-12
    assert mesh.num_faces > faces.shape[0]  # another connectivity


def test_the_undistorted_sequence_has_no_floor() -> None:
    # Issue 44's floor (registered STED_t 0.007 on horse, 0.11 on samba) came from the QEM of its remesh: with the
    # surface kept, the registered figures of the undistorted sequence are rounding (measured 2e-14 KG, 9e-16 STED_t).
    _, _, pair = _case("none", 0.0)
    assert kg_error(pair.original, pair.distorted).item() < 1e-10
    assert sted(pair.original, pair.distorted, pair.faces).sted.item() < 1e-10


def test_normal_flicker_is_seen_in_full() -> None:
    a, b, pair = _case("flicker", 0.002)
    exact, registered = sted(a, b, _performer()[1]), sted(pair.original, pair.distorted, pair.faces)
    # Measured: registered STED_t 0.0326 against the exact 0.03254 (+0.2 %); KG +8.5 % (the remeshed vertex set
    # samples the offset field elsewhere). Goal: the rise at least 0.95 of the exact.
    ratio = registered.temporal.item() / exact.temporal.item()
    assert 0.95 < ratio < 1.05
    assert abs(kg_error(pair.original, pair.distorted).item() / kg_error(a, b).item() - 1) < 0.15


def test_tangential_slide_is_invisible() -> None:
    a, b, pair = _case("slide", 0.002)
    exact, registered = sted(a, b, _performer()[1]), sted(pair.original, pair.distorted, pair.faces)
    # Measured: registered STED_t 0.0237 against the exact 0.2466 (0.096; what remains is the second-order normal
    # change of a slide on a curved surface). A tracking that saw tangential motion would be the exact's 1.0.
    assert registered.temporal.item() < 0.15 * exact.temporal.item()
