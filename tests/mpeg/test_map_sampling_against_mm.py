"""``map_sample`` against the ``mm`` binary's ``sample --mode map`` (skipped where it is absent): point by point,
in mm's order, bit for bit, with mm's colour bytes, on mmetric's textured test meshes (the cases of its
test-sample-map.sh) and the textured reference frame of ../shared/reference/mpeg/textured."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from tests.mpeg.conftest import MM, MM_TESTS, MPEG_REF
from tests.mpeg.mm_sampling import assert_same_rows_in_order, mm_sample
from torchmeshmetric.mpeg import TexturedMesh, load_textured_mesh, map_sample
from torchmeshmetric.structures import Mesh

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _check(obj: Path, texture: Path, tmp_path: Path) -> int:
    theirs = mm_sample(obj, texture, tmp_path, "map")
    pc = map_sample(load_textured_mesh(obj, texture))
    assert pc.colors is not None
    return assert_same_rows_in_order(pc, theirs)


@pytest.mark.parametrize(
    "name,texture",
    [
        ("plane", "plane.png"),
        ("plane_qp8", "plane_10_10.png"),
        ("plane_qp8", "plane.png"),
        ("plane_irregular", "plane_16_16.png"),
        ("degenerate", "plane.png"),
        ("pyramid", "plane.png"),
    ],
)
def test_mmetric_test_meshes(name: str, texture: str, tmp_path: Path) -> None:
    assert _check(TESTS / f"{name}.obj", TESTS / texture, tmp_path) > 0


@pytest.mark.skipif(not (MPEG_REF / "textured").is_dir(), reason="../shared/reference/mpeg absent")
def test_textured_frame(tmp_path: Path) -> None:
    ref = MPEG_REF / "textured" / "ref.obj"
    assert _check(ref, MPEG_REF / "textured" / "texture.png", tmp_path) > 1000


def test_needs_uvs_and_texture() -> None:
    tri = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
    with pytest.raises(ValueError, match="mesh: map sampling needs UVs and a texture; found no UVs"):
        map_sample(TexturedMesh(tri))


@pytest.mark.parametrize("chunk", [1, 7, 1000])
def test_runs_of_faces_give_the_points_of_one_run(chunk: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The candidate texels are taken in runs of faces (bounded memory: UVs outside [0, 1] planned 225 M texels at
    # once and were killed for memory, found by review); any run length gives the same points in the same order,
    # mmetric's (checked against mm above and here).
    import torchmeshmetric.mpeg.sampling.map_sampling as module

    mesh = load_textured_mesh(TESTS / "plane_irregular.obj", TESTS / "plane_16_16.png")
    whole = map_sample(mesh)
    monkeypatch.setattr(module, "_CHUNK", chunk)
    runs = map_sample(mesh)
    assert torch.equal(runs.points, whole.points) and torch.equal(runs.normals, whole.normals)
    assert runs.colors is not None and whole.colors is not None and torch.equal(runs.colors, whole.colors)
    assert _check(TESTS / "plane_irregular.obj", TESTS / "plane_16_16.png", tmp_path) == whole.num_points
