"""``prnd_sample`` against the ``mm`` binary's ``sample --mode prnd`` (skipped where it is absent): mmetric's
"pseudo-random" points are a deterministic R2 sequence, so they are compared point by point, in mm's order and bit
for bit, with mm's colour bytes, on mmetric's test meshes (the cases of its test-sample-prnd.sh) and a demo frame."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from tests.mpeg.mm_sampling import assert_same_rows_in_order, demo_frame_obj, library_mesh, mm_sample
from torchmeshmetric.mpeg import load_textured_mesh, prnd_sample

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _check(obj: Path, texture: Path | None, n: int, tmp_path: Path, *extra: str) -> int:
    theirs = mm_sample(obj, texture, tmp_path, "prnd", "--nbSamples", str(n), *extra)
    pc = prnd_sample(library_mesh(obj, texture), num_samples=n, bilinear="--bilinear" in extra)
    return assert_same_rows_in_order(pc, theirs)


@pytest.mark.parametrize(
    "name,texture,n,extra",
    [
        ("sphere", None, 50, ()),  # fewer samples than faces: the corners only
        ("sphere", None, 100000, ()),
        ("sphere_qp8", None, 20000, ()),
        ("degenerate", None, 1000, ()),
        ("triangles", None, 500, ()),  # corners keep their colour, inner points are black (as mm)
        ("plane", "plane.png", 50, ("--bilinear",)),
        ("plane_irregular", "plane_10_10.png", 5000, ()),
    ],
)
def test_mmetric_test_meshes(name: str, texture: str | None, n: int, extra: tuple[str, ...], tmp_path: Path) -> None:
    tex = TESTS / texture if texture else None
    assert _check(TESTS / f"{name}.obj", tex, n, tmp_path, *extra) >= n


def test_demo_frame(tmp_path: Path) -> None:
    obj, _num_verts, _num_faces = demo_frame_obj(tmp_path)
    assert _check(obj, None, 200000, tmp_path) >= 200000


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="num_samples: expected an integer >= 1, found 0"):
        prnd_sample(load_textured_mesh(TESTS / "pyramid.obj"), num_samples=0)
