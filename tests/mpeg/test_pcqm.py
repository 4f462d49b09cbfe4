"""PCQM without the ``mm`` binary: mmetric's own asserted figures, figures mm printed (stored), bad input, pieces."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from tests.mpeg.conftest import MM_TESTS
from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg import PointCloud, load_model_cloud, mpeg_pcqm, pcqm_lightness, vertex_sample

TESTS = MM_TESTS


def _first_two(capsys: pytest.CaptureFixture[str], args: list[str]) -> list[str]:
    assert main(["mpeg", *args, "--mode", "pcqm"]) == 0
    return capsys.readouterr().out.splitlines()[:2]


def test_mmetric_scripts_assertions(capsys: pytest.CaptureFixture[str]) -> None:
    """mmetric's test-compare-pcqm.sh asserts PCQM-PSNR=inf for these two (plane with itself, sphere vs qp8)."""
    plane, tex = str(TESTS / "plane.obj"), str(TESTS / "plane.png")
    args = [plane, plane, "--ref-texture", tex, "--dis-texture", tex, "--radius-factor", "1.0"]
    assert _first_two(capsys, args)[1] == "PCQM-PSNR=inf"
    assert _first_two(capsys, [str(TESTS / "sphere.obj"), str(TESTS / "sphere_qp8.obj")])[1] == "PCQM-PSNR=inf"


@pytest.mark.parametrize(
    ("a", "b", "extra", "printed"),
    [
        # printed by mm compare --mode pcqm (v1.1.7) on these meshes, with the same options
        (
            "plane.obj",
            "plane_irregular.obj",
            ["--ref-texture", "plane.png", "--dis-texture", "plane.png", "--radius-curvature", "0.05"],
            ["PCQM value is : 0.0293494974", "PCQM-PSNR=30.6479869"],
        ),
        (
            "plane.obj",
            "plane_irregular.obj",
            ["--ref-texture", "plane.png", "--dis-texture", "plane.png", "--radius-curvature", "0.2",
             "--threshold-knn-search", "8", "--radius-factor", "1.5"],
            ["PCQM value is : 0.0133196993", "PCQM-PSNR=37.5101117"],
        ),
        ("pyramid.obj", "triangles.obj", ["--radius-curvature", "0.3"],
         ["PCQM value is : 0.192826853", "PCQM-PSNR=14.2966498"]),
        ("sphere.obj", "sphere_qp8.obj", ["--radius-curvature", "0.05"],
         ["PCQM value is : 1.61772784e-41", "PCQM-PSNR=815.822261"]),
    ],
)  # fmt: skip
def test_figures_mm_printed(
    a: str, b: str, extra: list[str], printed: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    extra = [str(TESTS / x) if x.endswith(".png") else x for x in extra]
    assert _first_two(capsys, [str(TESTS / a), str(TESTS / b), *extra]) == printed


def test_json_keys_and_self_comparison(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    obj = tmp_path / "t.obj"
    obj.write_text("v 0 0 0 1 0 0\nv 4 0 0 0 1 0\nv 0 4 0 0 0 1\nv 4 4 0 1 1 0\nf 1 2 3\nf 2 4 3\n")
    assert main(["mpeg", str(obj), str(obj), "--mode", "pcqm", "--json", "--radius-curvature", "0.3"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["pcqm"] == 0.0 and d["pcqm_psnr"] == "inf"  # flat and the same colours: every quadric is z = 0
    assert d["points_ref"] == d["points_dis"] == load_model_cloud(obj).num_points
    assert (d["lightness"], d["lightness_structure"]) == (1.0, 1.0)
    # folded, the self-comparison is not 0: each point moves to its quadric (mm prints the same figures)
    obj.write_text("v 0 0 0 1 0 0\nv 4 0 0 0 1 0\nv 0 4 0 0 0 1\nv 4 4 1 1 1 0\nf 1 2 3\nf 2 4 3\n")
    args = [str(obj), str(obj), "--radius-curvature", "0.3"]
    assert _first_two(capsys, args) == ["PCQM value is : 5.32071905e-20", "PCQM-PSNR=385.480593"]


def test_a_distortion_scores_above_zero() -> None:
    g = torch.Generator().manual_seed(0)
    uv = torch.rand(3000, 2, generator=g)
    ref = torch.cat([uv, (uv[:, :1] - 0.5) ** 2], dim=1)  # a parabolic cylinder
    dis = ref + torch.tensor([0.0, 0.0, 0.01]) * torch.sin(9 * ref[:, :1])
    r = mpeg_pcqm(PointCloud(ref), PointCloud(dis), radius_curvature=0.05)
    assert 0.0 < r.pcqm < 1.0 and math.isfinite(r.psnr)
    assert r.pcqm_float == float(np.float32(r.pcqm))
    assert r.psnr == pytest.approx(-20 * math.log10(r.pcqm_float), rel=1e-12)  # mm's 10 log10(E^2 / (p E)^2)
    # colour: a lightness change scores on the 0.9771-weighted term
    grey = torch.full((3000, 3), 128.0)
    r2 = mpeg_pcqm(PointCloud(ref, colors=grey), PointCloud(ref, colors=grey * 1.5), radius_curvature=0.05)
    assert r2.features[1] < 1.0 and r2.pcqm > 0.01


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"knn": 0}, "knn"),
        ({"knn": True}, "knn"),
        ({"knn": 2.5}, "knn"),
        ({"radius_curvature": -1.0}, "radius_curvature"),
        ({"radius_curvature": math.nan}, "radius_curvature"),
        ({"radius_factor": 0.0}, "radius_factor"),
    ],
)
def test_bad_parameters_are_named(kwargs: dict[str, object], match: str) -> None:
    pc = PointCloud(torch.rand(10, 3))
    with pytest.raises(ValueError, match=match):
        mpeg_pcqm(pc, pc, **kwargs)  # type: ignore[arg-type]


def test_empty_cloud_is_refused() -> None:
    with pytest.raises(EmptyInputError, match="dis"):
        mpeg_pcqm(PointCloud(torch.rand(5, 3)), PointCloud(torch.zeros(0, 3)))


def test_degenerate_inputs_are_named() -> None:
    from torchmeshmetric._checks import NonFiniteError

    pc = PointCloud(torch.rand(5, 3))
    with pytest.raises(ValueError, match="box measure"):  # a single point at the origin: radius 0, means 0/0
        mpeg_pcqm(PointCloud(torch.zeros(1, 3)), pc)
    bad = PointCloud(torch.rand(5, 3), colors=torch.full((5, 3), math.nan))
    with pytest.raises(NonFiniteError, match=r"dis\.colors"):
        mpeg_pcqm(pc, bad)


def test_cli_bad_option_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    obj = tmp_path / "t.obj"
    obj.write_text("v 0 0 0\nv 4 0 0\nv 0 4 0\nf 1 2 3\n")
    assert main(["mpeg", str(obj), str(obj), "--mode", "pcqm", "--threshold-knn-search", "0"]) == 1
    assert "--threshold-knn-search: expected an integer >= 1, found 0" in capsys.readouterr().err  # the option


def test_fewer_points_than_knn() -> None:
    """PCQM pads a short neighbour list with point 0 (its zero-initialised index vector): finite, not a crash."""
    pts = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.2]])
    r = mpeg_pcqm(PointCloud(pts), PointCloud(pts * 1.01), radius_curvature=0.5)
    assert math.isfinite(r.pcqm)


def test_lightness_table() -> None:
    levels = np.arange(256, dtype=np.float64)
    grey = pcqm_lightness(np.stack([levels] * 3, axis=1))
    assert grey[0] == 0.0 and np.all(np.diff(grey) > 0)  # monotone in L*
    assert grey[-1] == pytest.approx(75.1522, abs=1e-4)  # white: L* just below 100, next to the table's 75.1532
    # colours are truncated to integers first (PCQM's int parameters)
    assert np.array_equal(pcqm_lightness(np.array([[10.9, 20.2, 30.99]])), pcqm_lightness(np.array([[10, 20, 30]])))


def test_mesh_points_in_mm_order() -> None:
    """PCQM's tie-breaking depends on the point order: vertex_sample gives mmetric's push order."""
    verts = torch.tensor([[0.0, 0, 0], [4, 0, 0], [0, 4, 0], [4, 4, 1]])
    faces = torch.tensor([[0, 1, 2], [1, 3, 2]])
    ordered = vertex_sample((verts, faces)).points.numpy()
    # face 0 first: its corners, then its midpoints depth first (level 1 before its children's level 2)
    assert ordered[:6].tolist() == [[0, 0, 0], [4, 0, 0], [0, 4, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]]
