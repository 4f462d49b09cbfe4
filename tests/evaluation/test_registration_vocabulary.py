"""One registration vocabulary: the evaluation takes ``NonRigidOptions`` as the losses do, and one warp conversion."""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric import ShapeError
from torchmeshmetric.evaluation import TemporalConsistency, evaluate_sequence, registration_settings
from torchmeshmetric.evaluation.pipeline import registration_keywords
from torchmeshmetric.registration import CachedRegistration, NonRigidOptions, SurfaceWarp, as_warp
from torchmeshmetric.structures import as_mesh


def test_options_as_a_nonrigidoptions_or_as_keywords_are_one_registration():
    # a NonRigidOptions was refused by the evaluation (dict() of it), while the temporal loss took it
    given = NonRigidOptions(num_points=500, tolerance=0.02)
    spelled = {"num_points": 500, "tolerance": 0.02}
    assert registration_settings(None, registration_keywords(given)) == registration_settings(None, spelled)
    metric = TemporalConsistency(registration_options=given)
    assert registration_settings(None, metric.registration_options) == registration_settings(None, spelled)
    with pytest.raises(TypeError, match=r"registration_options: expected NonRigidOptions, a mapping"):
        registration_keywords(["num_points", 500])


def test_one_conversion_of_a_registration_to_a_warp():
    sphere = as_mesh(trimesh.creation.icosphere(subdivisions=1))
    moved = sphere.verts + torch.tensor([0.25, 0.0, 0.0], dtype=sphere.dtype)
    for given in ((moved, sphere.faces), CachedRegistration(moved, torch.zeros(len(moved)), True, 0.0, None)):
        warp = as_warp(given, sphere, sphere, name="registration")
        assert isinstance(warp, SurfaceWarp)
        assert torch.allclose(warp(sphere.verts), moved, atol=1e-12)  # the registered vertices, reproduced
    assert as_warp(abs, sphere, sphere, name="registration") is abs  # a callable is a warp
    with pytest.raises(ShapeError, match=r"registration: expected registered vertices of shape \(42, 3\)"):
        as_warp((moved[:-1], sphere.faces[:10]), sphere, sphere, name="registration")
    with pytest.raises(TypeError, match=r"registration: expected None, a warp"):
        as_warp(3, sphere, sphere, name="registration")


def test_a_device_among_the_registration_options_is_refused_by_name():
    # Review I #9: torch's "default_register() got multiple values for keyword argument 'device'" named an internal
    # function; the device is the evaluation's own argument.
    frames = [trimesh.creation.icosphere(subdivisions=1)] * 2
    with pytest.raises(TypeError, match=r"^registration_options: 'device' is not a registration option"):
        evaluate_sequence(frames, frames, registration_options={"device": "cpu", "num_points": 50})
    with pytest.raises(TypeError, match=r"^registration_options: 'device' is not a registration option"):
        TemporalConsistency(registration_options={"device": "cpu"})
    assert registration_keywords({"num_threads": 1}) == {"num_threads": 1}  # run arguments pass through
