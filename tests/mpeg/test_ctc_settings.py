"""CtcSettings: one record of the CTC chain's settings, and the old keywords resolved to it in one place."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.mpeg.ctc.chain import ctc_frame, ctc_sequence
from torchmeshmetric.mpeg.ctc.face_errors import ctc_face_errors
from torchmeshmetric.mpeg.ctc.settings import CtcSettings, box_longest_side, resolve_settings
from torchmeshmetric.structures import Mesh

BOX = {"min_pos": [-1.0, -1.0, -1.0], "max_pos": [1.0, 1.0, 1.0]}


def _quantised(subdivisions: int, scale: float) -> TexturedMesh:
    s = trimesh.creation.icosphere(subdivisions)
    verts = np.round((s.vertices * scale + 1) * 511.5)
    return TexturedMesh(Mesh(torch.tensor(verts), torch.tensor(s.faces)))


def test_defaults_are_the_test_model() -> None:
    s = CtcSettings(qp=10, qt=12, **BOX)
    assert (s.decoded_qt, s.grid_size, s.ibsm_resolution, s.ibsm_cameras) == (0, 1024, 2048, 16)
    assert s.resolution is None and s.peak == 2.0 and s.box == (BOX["min_pos"], BOX["max_pos"])
    assert CtcSettings(qp=10, qt=12, resolution=1.5, **BOX).peak == 1.5


def test_box_longest_side() -> None:
    assert box_longest_side([0, -1, 2], [0.5, 3, 2.25]) == 4.0


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf")])
def test_resolution_checked_once(bad: float) -> None:
    with pytest.raises(ValueError, match=r"^resolution: expected a positive finite PSNR peak"):
        CtcSettings(qp=10, qt=12, resolution=bad, **BOX)


def test_resolution_type() -> None:
    with pytest.raises(TypeError, match=r"^resolution: expected a real number, found str"):
        CtcSettings(qp=10, qt=12, resolution="2", **BOX)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("qp", 32, r"^qp: expected an integer bit depth in 0\.\.31, found 32"),
        ("qp", 10.5, r"^qp: expected an integer bit depth in 0\.\.31, found 10\.5"),
        ("qt", -1, r"^qt: expected an integer bit depth in 0\.\.31, found -1"),
        ("decoded_qt", True, r"^decoded_qt: expected an integer bit depth in 0\.\.31, found True"),
        ("min_pos", [0, 0], r"^min_pos: expected 3 finite numbers, found \[0, 0\]"),
        ("max_pos", [1, float("inf"), 1], r"^max_pos: expected 3 finite numbers"),
        ("max_pos", [1, -2, 1], r"^max_pos: \[1\.0, -2\.0, 1\.0\] is below min_pos \[-1\.0, -1\.0, -1\.0\]"),
        ("grid_size", 1, r"^grid_size: expected an integer >= 2, found 1"),
        ("grid_size", 1024.0, r"^grid_size: expected an integer >= 2, found 1024\.0"),
        ("ibsm_resolution", 0, r"^ibsm_resolution: expected an integer >= 1 \(or None: no IBSM\), found 0"),
        ("ibsm_cameras", 1, r"^ibsm_cameras: expected an integer >= 2 \(mmetric's Fibonacci sphere\), found 1"),
    ],
)
def test_every_field_checked_by_name(field: str, value: object, message: str) -> None:
    """At construction, under the field's own name (the chain's inner checks name their own arguments)."""
    with pytest.raises(ValueError, match=message):
        CtcSettings(**{"qp": 10, "qt": 12, **BOX, field: value})  # type: ignore[arg-type]


def test_numpy_and_tensor_fields_accepted() -> None:
    s = CtcSettings(qp=np.int64(10), qt=12, min_pos=torch.zeros(3), max_pos=np.ones(3), grid_size=np.int32(16))
    assert s.peak == 1.0 and s.grid_size == 16


def test_resolve_keywords() -> None:
    s = resolve_settings(None, qp=10, qt=0, ibsm_resolution=None, grid_size=1024, **BOX)
    assert s == CtcSettings(qp=10, qt=0, ibsm_resolution=None, **BOX)
    settings = CtcSettings(qp=10, qt=0, **BOX)
    assert resolve_settings(settings, qp=None, grid_size=1024, ibsm_resolution=2048) is settings


def test_resolve_refuses_both_and_missing() -> None:
    settings = CtcSettings(qp=10, qt=0, **BOX)
    with pytest.raises(TypeError, match=r"^grid_size: give the chain's settings either as settings= or as keywords"):
        resolve_settings(settings, grid_size=64)
    with pytest.raises(TypeError, match=r"^ibsm_resolution: give"):
        resolve_settings(settings, ibsm_resolution=None)
    with pytest.raises(TypeError, match=r"^max_pos: required \(or pass settings=CtcSettings"):
        resolve_settings(None, qp=10, qt=0, min_pos=[0, 0, 0], max_pos=None)
    with pytest.raises(TypeError, match=r"^settings: expected a CtcSettings, found dict"):
        resolve_settings({"qp": 10})  # type: ignore[arg-type]


def test_settings_and_keywords_give_identical_results() -> None:
    ref, dis = _quantised(2, 1.0), _quantised(1, 0.97)
    keywords = {"qp": 10, "qt": 0, "resolution": 2.0, "grid_size": 64, "ibsm_resolution": 64, "ibsm_cameras": 4}
    settings = CtcSettings(**keywords, **BOX)  # type: ignore[arg-type]
    a = ctc_frame(ref, dis, **keywords, **BOX, frame=3)  # type: ignore[arg-type]
    b = ctc_frame(ref, dis, settings, frame=3)
    assert a == b and a.figures["GridD1"] < 99 and "IbsmGeom" in a.figures
    seq = ctc_sequence([(3, ref, dis)], settings)
    assert seq.frames == [b]
    fa = ctc_face_errors(ref, dis, qp=10, qt=0, grid_size=64, **BOX)
    fb = ctc_face_errors(ref, dis, CtcSettings(qp=10, qt=0, grid_size=64, **BOX))
    np.testing.assert_array_equal(fa.d1_max, fb.d1_max)
    np.testing.assert_array_equal(fa.samples, fb.samples)
