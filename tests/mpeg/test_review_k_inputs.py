"""Review K's input checks of the MPEG comparisons: the PSNR peak, 8-bit colours, PCQM's radii, D2 normals.

Where mm gives a figure for the input (a one-point reference box: ``-inf``), the library gives mm's figure, checked
against mm where it is present; otherwise a typed error naming the argument.
"""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch

from tests.mpeg.conftest import MM
from torchmeshmetric._checks import NonFiniteError
from torchmeshmetric.mpeg.comparison.losses import mpeg_geometry_loss, point_to_plane_mse
from torchmeshmetric.mpeg.comparison.pcc import mpeg_compare
from torchmeshmetric.mpeg.comparison.pcqm import mpeg_pcqm
from torchmeshmetric.mpeg.comparison.psnr import mpeg_psnr
from torchmeshmetric.mpeg.core.point_cloud import PointCloud

_A = PointCloud(torch.tensor([[1.0, 2, 3]]), normals=torch.tensor([[0.0, 0, 1]]), colors=torch.tensor([[10.0, 20, 30]]))
_B = PointCloud(torch.tensor([[1.0, 2, 4]]), colors=torch.tensor([[10.0, 20, 40]]))


@pytest.mark.parametrize(
    ("peak", "error", "match"),
    [
        (0.0, ValueError, "peak: expected a positive finite number, found 0.0"),
        (-1.0, ValueError, "peak: expected a positive finite number, found -1.0"),
        (float("nan"), ValueError, "peak: expected a positive finite number, found nan"),
        (float("inf"), ValueError, "peak: expected a positive finite number, found inf"),
        (1e39, ValueError, "peak: .*float32's range.* rounds to inf"),
        (1e-50, ValueError, "peak: .*float32's range.* rounds to 0.0"),
        ("1", TypeError, "peak: expected a float, found str"),
    ],
)
def test_mpeg_compare_refuses_bad_peak(peak: object, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        mpeg_compare(_A, _B, peak=peak)  # type: ignore[arg-type]


def test_peak_as_numpy_or_tensor_number() -> None:
    ref = mpeg_compare(_A, _B, peak=2.0).symmetric.d1_psnr
    assert mpeg_compare(_A, _B, peak=np.float32(2.0)).symmetric.d1_psnr == ref  # type: ignore[arg-type]
    assert mpeg_compare(_A, _B, peak=torch.tensor(2.0)).symmetric.d1_psnr == ref  # type: ignore[arg-type]


def test_one_point_reference_box_gives_mm_figures() -> None:
    """mm prints ``-inf`` for a positive error and ``-nan`` for a zero one when the reference box is one point."""
    r = mpeg_compare(_A, _B)
    assert r.peak == 0.0
    for d in (r.ref_to_dis, r.dis_to_ref, r.symmetric):
        assert d.d1_psnr == -math.inf and d.d2_psnr == -math.inf
    assert r.ref_to_dis.d1_hausdorff_psnr == -math.inf
    assert round(r.symmetric.color_psnr[0], 7) == 50.9600687  # colour PSNRs do not use the box (mm's figure)
    two = PointCloud(torch.tensor([[1.0, 2, 3]] * 2), normals=torch.tensor([[0.0, 0, 1]] * 2))
    r = mpeg_compare(two, PointCloud(torch.tensor([[1.0, 2, 3], [1, 2, 5]])))
    assert r.ref_to_dis.d1_mse == 0.0 and math.isnan(r.ref_to_dis.d1_psnr)  # mm: mse1 0, PSNR -nan
    assert r.dis_to_ref.d1_psnr == -math.inf


def test_mpeg_psnr_zero_peak_and_bad_arguments() -> None:
    assert mpeg_psnr(1.0, 0.0) == -math.inf
    assert math.isnan(mpeg_psnr(0.0, 0.0))
    assert mpeg_psnr(math.inf, 1.0) == -math.inf
    assert math.isnan(mpeg_psnr(math.nan, 1.0))
    with pytest.raises(ValueError, match=r"mse: expected a squared error >= 0, found -1\.0"):
        mpeg_psnr(-1.0, 1.0)
    with pytest.raises(ValueError, match=r"peak: expected a finite number >= 0, found -1\.0"):
        mpeg_psnr(1.0, -1.0)


def _write_ply(path: Path, pts: np.ndarray, cols: np.ndarray | None = None, normals: np.ndarray | None = None) -> None:
    head = ["ply", "format ascii 1.0", f"element vertex {len(pts)}", *(f"property float {c}" for c in "xyz")]
    head += [f"property float n{c}" for c in "xyz"] if normals is not None else []
    head += [f"property uchar {c}" for c in ("red", "green", "blue")] if cols is not None else []
    rows = []
    for i, p in enumerate(pts):
        row = [repr(float(v)) for v in p]
        row += [repr(float(v)) for v in normals[i]] if normals is not None else []
        row += [str(int(v)) for v in cols[i]] if cols is not None else []
        rows.append(" ".join(row))
    path.write_text("\n".join([*head, "end_header", *rows]) + "\n")


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
def test_one_point_reference_box_against_mm(tmp_path: Path) -> None:
    _write_ply(tmp_path / "a.ply", np.array([[1.0, 2, 3]]), np.array([[10, 20, 30]]), np.array([[0.0, 0, 1]]))
    _write_ply(tmp_path / "b.ply", np.array([[1.0, 2, 4]]), np.array([[10, 20, 40]]))
    out = subprocess.run(
        [str(MM), "compare", "--mode", "pcc", "--inputModelA", str(tmp_path / "a.ply"), "--inputModelB",
         str(tmp_path / "b.ply")], capture_output=True, text=True, check=False,
    ).stdout  # fmt: skip
    lines = {k.strip(): v.strip() for k, _, v in (ln.partition(":") for ln in out.splitlines() if ":" in ln)}
    r = mpeg_compare(_A, _B)
    assert lines["mseF,PSNR (p2point)"] == "-inf" and r.symmetric.d1_psnr == -math.inf
    assert lines["mseF,PSNR (p2plane)"] == "-inf" and r.symmetric.d2_psnr == -math.inf
    assert lines["c[0],PSNRF"] == f"{r.symmetric.color_psnr[0]:.9g}"


def _cloud(colors: torch.Tensor) -> PointCloud:
    g = torch.Generator().manual_seed(0)
    return PointCloud(torch.rand(colors.shape[0], 3, generator=g), colors=colors)


@pytest.mark.parametrize(
    ("colors", "match"),
    [
        (torch.full((20, 3), 300.0), r"found values in \[300, 300\]"),
        (torch.full((20, 3), -5.0), r"found values in \[-5, -5\]"),
        (torch.linspace(0.0, 1.0, 60).reshape(20, 3), r"found fractions in \[0, 1\].*multiply them by 255"),
    ],
)
def test_colours_off_the_8_bit_scale_refused(colors: torch.Tensor, match: str) -> None:
    good = _cloud(torch.full((20, 3), 128.0))
    for fn in (mpeg_compare, mpeg_pcqm):
        with pytest.raises(ValueError, match="dis.colors: expected 8-bit RGB values in \\[0, 255\\], " + match):
            fn(good, _cloud(colors))  # type: ignore[operator]
        with pytest.raises(ValueError, match=r"ref\.colors: expected 8-bit RGB values"):
            fn(_cloud(colors), good)  # type: ignore[operator]


def test_integer_colours_in_0_1_still_accepted() -> None:
    """Black and near-black 8-bit colours are colours: only fractions of [0, 1] are taken for normalised ones."""
    c = torch.tensor([[0.0, 1, 0]] * 20)
    assert mpeg_compare(_cloud(c), _cloud(c), peak=1.0).symmetric.color_mse == (0.0, 0.0, 0.0)


def _pcqm_clouds() -> tuple[PointCloud, PointCloud]:
    g = torch.Generator().manual_seed(0)
    a = torch.rand(300, 3, generator=g)
    c = torch.randint(0, 256, (300, 3), generator=g).float()
    return PointCloud(a, colors=c), PointCloud(a + 0.01 * torch.rand(300, 3, generator=g), colors=c)


def test_pcqm_radius_as_numpy_or_tensor_number() -> None:
    a, b = _pcqm_clouds()
    for rc in (np.float32(0.05), torch.tensor(0.05, dtype=torch.float64), torch.tensor([0.05]), np.float64(0.05)):
        expected = mpeg_pcqm(a, b, radius_curvature=float(rc)).pcqm  # the same number as a Python float
        assert mpeg_pcqm(a, b, radius_curvature=rc).pcqm == expected  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="radius_factor: expected a float, found str"):
        mpeg_pcqm(a, b, radius_factor="2")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"radius_curvature: expected a positive finite number, found -1\.0"):
        mpeg_pcqm(a, b, radius_curvature=-1.0)


def test_pcqm_overflowing_pooling_radius_refused() -> None:
    """mm prints -nan when radius_curvature * box * radius_factor overflows; the library refuses it."""
    a, b = _pcqm_clouds()
    with pytest.raises(ValueError, match=r"radius_curvature, radius_factor: .* overflows to inf"):
        mpeg_pcqm(a, b, radius_curvature=1e200, radius_factor=1e200)
    assert math.isfinite(mpeg_pcqm(a, b, radius_curvature=1e100, radius_factor=1e100).pcqm)  # pooling² overflows


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_d2_loss_refuses_non_finite_normals(bad: float) -> None:
    g = torch.Generator().manual_seed(0)
    p, q = torch.rand(10, 3, generator=g), torch.rand(12, 3, generator=g)
    n = torch.nn.functional.normalize(torch.rand(12, 3, generator=g), dim=1)
    n[3, 1] = bad
    with pytest.raises(NonFiniteError, match="ref_normals: expected finite values"):
        point_to_plane_mse(p, q, n)
    nd = torch.nn.functional.normalize(torch.rand(10, 3, generator=g), dim=1)
    with pytest.raises(NonFiniteError, match="dis_normals: expected finite values"):
        mpeg_geometry_loss(
            p, q, term="d2", ref_normals=n.nan_to_num(0.0), dis_normals=nd.index_fill(0, torch.tensor([2]), bad)
        )


def test_more_than_30_equidistant_neighbours_keep_the_30_first_by_position() -> None:
    """The library's documented rule (docs/mpeg.md): of more than 30 exactly equidistant neighbours, the 30 first of
    the merged cloud (sorted by x, y, z) are averaged. mm averages the 30 its k-d tree visits first, another subset.
    """
    r = np.arange(-10, 11)
    grid = np.stack(np.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3)
    shell = grid[(grid * grid).sum(1) == 50].astype(np.float32)  # 84 integer points at distance sqrt(50)
    assert shell.shape[0] == 84
    first30 = np.lexsort((shell[:, 2], shell[:, 1], shell[:, 0]))[:30]
    colours = np.full((84, 3), 200.0, np.float32)
    colours[first30] = 40.0
    perm = np.random.default_rng(0).permutation(84)  # the input order does not matter: the merge sorts
    ref = PointCloud(torch.zeros(1, 3), colors=torch.tensor([[40.0, 40, 40]]))
    dis = PointCloud(torch.from_numpy(shell[perm]), colors=torch.from_numpy(colours[perm]))
    assert mpeg_compare(ref, dis, peak=10.0).ref_to_dis.color_mse == (0.0, 0.0, 0.0)
