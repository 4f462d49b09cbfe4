"""A stray unreferenced vertex in the target changes no registration (review I #1).

The kernels centred the target on the bounding box of every vertex and the registration took its range scale
(``_common.coordinate_scale``) from every vertex's ``|coordinate|``. One unreferenced vertex far away (captured frames
carry them) moved the centre off the surface, or scaled a unit float32 target by 2**-20 (stray at 1e6) or 2**-30
(1e9), and the registration lost its digits: the rigid ICP did not converge, the non-rigid fit was "implausible"
with a residual of 2.64 diagonals (float32, stray at 1e9). Both now come from the referenced vertices, so the
registration onto the target with the stray vertex is the registration onto the target without it, bit for bit.
"""

from __future__ import annotations

import warnings

import pytest
import torch

from tests.registration.test_extreme_scales import _pair
from torchmeshmetric import Mesh, NonFiniteError, register_nonrigid, register_rigid
from torchmeshmetric.registration._common import coordinate_scale, normalisation

STRAYS = [(torch.float32, 1e4), (torch.float32, 1e6), (torch.float32, 1e9), (torch.float64, 1e15)]


def _stray(verts: torch.Tensor, far: float) -> torch.Tensor:
    return torch.cat([verts, torch.tensor([[far, -far, 0.0]], dtype=verts.dtype)])


@pytest.mark.parametrize(("dtype", "far"), STRAYS)
def test_the_frame_and_the_scale_ignore_the_stray_vertex(dtype: torch.dtype, far: float) -> None:
    _, (w, f) = _pair(dtype, 1.0)
    target = Mesh(_stray(w, far), f)
    # Old: 2**-14 (1e4), 2**-20 (1e6), 2**-30 (1e9) for float32.
    assert coordinate_scale(target) == 1.0
    center, diag = normalisation(target)
    clean_center, clean_diag = normalisation(Mesh(w, f))
    assert torch.equal(center, clean_center) and torch.equal(diag, clean_diag)


@pytest.mark.parametrize(("dtype", "far"), STRAYS)
def test_registration_onto_a_target_with_a_stray_vertex_is_that_onto_the_clean_target(
    dtype: torch.dtype, far: float
) -> None:
    (v, f), (w, _) = _pair(dtype, 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # converged: no RegistrationWarning
        clean = register_nonrigid((v, f), (w, f))
        got = register_nonrigid((v, f), (_stray(w, far), f))
    assert got.converged and clean.converged
    assert torch.equal(got.verts, clean.verts) and torch.equal(got.residual, clean.residual)
    assert got.loss_history == clean.loss_history
    rigid = [
        register_rigid((v, f), (t, f), point_to_plane=True, generator=torch.Generator().manual_seed(0))
        for t in (w, _stray(w, far))
    ]
    # (This deformed pair is no rigid motion: plain ICP stops at its 30 iterations either way.)
    assert torch.equal(rigid[1].transform, rigid[0].transform) and torch.equal(rigid[1].verts, rigid[0].verts)
    assert rigid[1].iterations == rigid[0].iterations and rigid[1].converged == rigid[0].converged


def test_the_refusal_of_a_mesh_too_small_for_its_coordinates_names_its_surface_not_the_stray_vertex() -> None:
    # A unit ellipsoid 1e5 from the origin in float32 is refused (its areas are rounding noise); the message gave the
    # largest |coordinate| of every vertex, 1e+09 with a stray vertex there, and now that of the surface.
    (sv, sf), (tv, tf) = _pair(torch.float64, 1.0)
    shift = torch.tensor([1e5, -5e4, 0.0], dtype=torch.float64)
    source = (_stray(sv + shift, 1e9).float(), sf)
    with pytest.raises(ValueError, match=r"source: every face .* float32 coordinates \(up to 1e\+05 from the origin\)"):
        register_nonrigid(source, ((tv + shift).float(), tf))


@pytest.mark.parametrize("side", ["source", "target"])
def test_a_stray_vertex_beyond_the_range_of_a_tiny_surfaces_frame_is_refused_in_words(side: str) -> None:
    # A float32 surface of 1e-20 units is scaled by 2**66 for the registration; an unreferenced vertex at 1e30 then
    # overflows (7e49). The rigid registration of such a source returned Inf vertices, the others refused with
    # "verts: expected finite values" (and, while the scale came from every vertex, "expected a surface with
    # positive area": the surface underflowed).
    (v, f), (w, _) = _pair(torch.float32, 1e-20)
    pair = {"source": (v, f), "target": (w, f)}
    pair[side] = (_stray(pair[side][0], 1e30), f)
    for register in (register_rigid, register_nonrigid):
        with pytest.raises(NonFiniteError, match=rf"{side}: an unreferenced vertex \(up to 1e\+30 from the origin\)"):
            register(pair["source"], pair["target"])
