"""IBSM's renderings and sums, pinned bit for bit: made by the rasteriser of 2026-12-04 (before the speed work).

The rasteriser does mmetric's float32 arithmetic in its order (``tests/mpeg/test_ibsm.py`` compares the figures with
``mm``, which needs ``../shared``); this file pins the buffers themselves, on meshes in the repository, so that any
change to the rasteriser (bands, edge functions, divisions) that moves one bit of depth or colour fails here. The
values were printed by the code as of commit 82fd045 (the SHA-256 covers the float32 depth bytes then the RGBA bytes).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from torchmeshmetric.mpeg.comparison.ibsm import ibsm, ibsm_render
from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh

DATA = Path(__file__).resolve().parents[1] / "data" / "mmetric"


@pytest.mark.pinned
@pytest.mark.parametrize(
    ("obj", "png", "direction", "box", "sha", "rng", "covered", "pixels"),
    [
        (
            "sphere.obj", None, (0.3, 0.5, 0.8), ((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)),
            "1f01fa78a51aadf9b9eff4dbe08080f28b8aff588cb5063260012f18ef69c4df", 3.0 - 2.0**-22, 1148,
            {(33, 33): ("-0x1.6eeee2p+0", [255, 0, 0, 255]), (20, 41): ("-0x1.aa9a34p+0", [255, 0, 0, 255])},
        ),
        (
            "plane.obj", "plane.png", (0.2, -0.3, -0.9), ((-5.0, -5.0, -0.1), (5.0, 5.0, 0.1)),
            "1c6e16223a211d31e6992b6878fe064f097ca880425632266afbc1d4fa858b97", 3.0, 2054,
            {(33, 33): ("-0x1.fddd2p+0", [132, 161, 155, 255]), (20, 41): ("-0x1.ebd31p+0", [44, 178, 236, 255])},
        ),
    ],
)  # fmt: skip
def test_rendering_is_pinned(
    obj: str,
    png: str | None,
    direction: tuple[float, float, float],
    box: tuple[tuple[float, float, float], tuple[float, float, float]],
    sha: str,
    rng: float,
    covered: int,
    pixels: dict[tuple[int, int], tuple[str, list[int]]],
) -> None:
    """A 67 x 67 rendering (odd size: a partial last band) of an untextured sphere and of a textured plane."""
    mesh = load_textured_mesh(DATA / obj, None if png is None else DATA / png)
    z, rgba, got_rng = ibsm_render(mesh, direction, box, resolution=67)
    assert got_rng == rng
    assert int((rgba[..., 3] > 0).sum()) == covered
    for (i, j), (depth, colour) in pixels.items():
        assert float(z[i, j]) == float.fromhex(depth), (i, j)
        assert rgba[i, j].tolist() == colour, (i, j)
    assert hashlib.sha256(z.numpy().tobytes() + rgba.numpy().tobytes()).hexdigest() == sha


@pytest.mark.pinned
def test_sums_are_pinned() -> None:
    """The pooled figures of two pairs over 5 cameras at resolution 97: geometry only, and texture and geometry."""
    r = ibsm(
        load_textured_mesh(DATA / "sphere.obj"), load_textured_mesh(DATA / "sphere_qp8.obj"), resolution=97, cameras=5
    )
    assert (r.pixels, r.geo_mse, r.unmatched_percent) == (
        11975, float.fromhex("0x1.457251482c632p-4"), float.fromhex("0x1.2f90d5c75940bp-1"))  # fmt: skip
    assert r.rgb_mse == (0.0, 0.0, 0.0, 0.0)
    r = ibsm(
        load_textured_mesh(DATA / "plane.obj", DATA / "plane.png"),
        load_textured_mesh(DATA / "plane_irregular.obj", DATA / "plane_16_16.png"),
        resolution=97,
        cameras=5,
    )
    assert (r.pixels, r.geo_mse, r.unmatched_percent) == (4624, float.fromhex("0x1.1e9fp-33"), 0.0)
    hexes = ["0x1.8ac55d02a84dfp+11", "0x1.ae8fc038b129ap+9", "0x1.1f2f878787878p+10", "0x1.aeab608dbae81p+10"]
    assert r.rgb_mse == tuple(float.fromhex(h) for h in hexes)
    hexes = ["0x1.1ce57ae24e48dp+9", "0x1.2e6f4f70cba35p+7", "0x1.1ef1566a76d3dp+10", "0x1.26dbec3fdec8bp+9"]
    assert r.yuv_mse == tuple(float.fromhex(h) for h in hexes)
