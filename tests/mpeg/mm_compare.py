"""What the ``equ`` and ``eqTFAN`` tests against ``mm compare`` share: the block of lines mm prints for the comparison,
small OBJ / PLY / PNG builders, and the built cases (normals, colours, UV lists, texture maps) both modes are run on."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
from PIL import Image

from tests.mpeg.conftest import MM

HEADERS = {"equ": "  Epsilon = ", "eqTFAN": "  eqTFAN_Epsilon = "}
"""The line mm prints last before the comparison's own lines, per mode."""


def mm_block(mode: str, a: Path, b: Path, *options: str, maps: tuple[Path | None, Path | None] = (None, None)) -> str:
    """Every line ``mm compare --mode MODE`` prints for the comparison itself: after its ``Epsilon = `` header line,
    before ``Time on processing`` (``maps``: ``--inputMapA`` / ``--inputMapB``)."""
    args = [str(MM), "compare", "--mode", mode, "--inputModelA", str(a), "--inputModelB", str(b), *options]
    for option, m in zip(("--inputMapA", "--inputMapB"), maps, strict=True):
        args += [option, str(m)] if m is not None else []
    out = subprocess.run(args, capture_output=True, text=True, timeout=60, check=True, cwd=a.parent).stdout.splitlines()
    start = next(i for i, line in enumerate(out) if line.startswith(HEADERS[mode]))
    stop = next(i for i, line in enumerate(out) if line.startswith("Time on processing"))
    return "\n".join(out[start + 1 : stop])


# ----------------------------------------------------------------------------------------------- builders
QUAD = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)]
TRIS = [(0, 1, 2), (0, 2, 3)]
UP = [(0.0, 0.0, 1.0)] * 4
TILTED = [(0.0, 0.0, 1.0), (0.0, 0.6, 0.8), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0)]
UV4 = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
PER_CORNER = [(0, 1, 2), (0, 2, 3)]


def obj(
    path: Path,
    *,
    colors: list[tuple[float, float, float] | None] | None = None,
    normals: list[tuple[float, float, float]] | None = None,
    normal_index: bool = False,
    uvs: list[tuple[float, float]] | None = None,
    corner_uvs: list[tuple[int, int, int]] | None = None,
    mtl: str | None = None,
    verts: list[tuple[float, float, float]] = QUAD,
    tris: list[tuple[int, int, int]] = TRIS,
) -> Path:
    """A small OBJ: ``v`` (with a colour where given), ``vn``, ``vt`` and faces of the chosen corner form."""
    lines = [f"mtllib {mtl}"] if mtl else []
    for k, v in enumerate(verts):
        c = colors[k] if colors is not None and k < len(colors) else None
        lines.append("v " + " ".join(f"{x:g}" for x in v) + ("" if c is None else " " + " ".join(f"{x:g}" for x in c)))
    lines += ["vn " + " ".join(f"{x:g}" for x in n) for n in normals or []]
    lines += ["vt " + " ".join(f"{x:g}" for x in t) for t in uvs or []]
    for j, tri in enumerate(tris):
        if corner_uvs is not None:
            normal = [f"/{i + 1}" if normal_index else "" for i in tri]
            corners = [f"{i + 1}/{t + 1}{n}" for i, t, n in zip(tri, corner_uvs[j], normal, strict=True)]
        else:
            corners = [f"{i + 1}//{i + 1}" if normal_index else f"{i + 1}" for i in tri]
        lines.append("f " + " ".join(corners))
    path.write_text("\n".join(lines) + "\n")
    return path


def ply(
    path: Path,
    *,
    colors: list[tuple[int, int, int]] | None = None,
    normals: list[tuple[float, float, float]] | None = None,
    uvs: list[tuple[float, float]] | None = None,
) -> Path:
    """An ASCII PLY of the quad with optional ``red green blue``, ``nx ny nz`` and ``texture_u texture_v``."""
    props = ["x", "y", "z"]
    types = ["float"] * 3
    if normals is not None:
        props += ["nx", "ny", "nz"]
        types += ["float"] * 3
    if colors is not None:
        props += ["red", "green", "blue"]
        types += ["uchar"] * 3
    if uvs is not None:
        props += ["texture_u", "texture_v"]
        types += ["float"] * 2
    head = ["ply", "format ascii 1.0", f"element vertex {len(QUAD)}"]
    head += [f"property {t} {p}" for t, p in zip(types, props, strict=True)]
    head += [f"element face {len(TRIS)}", "property list uchar int vertex_indices", "end_header"]
    rows = []
    for k, v in enumerate(QUAD):
        row = (
            list(v)
            + list(normals[k] if normals else [])
            + list(colors[k] if colors else [])
            + list(uvs[k] if uvs else [])
        )
        rows.append(" ".join(f"{x:g}" for x in row))
    rows += [f"3 {a} {b} {c}" for a, b, c in TRIS]
    path.write_text("\n".join(head + rows) + "\n")
    return path


def png(path: Path, size: tuple[int, int], changed: int = 0) -> Path:
    """A random (seeded) RGB image of ``size`` = (width, height); its first ``changed`` texels differ in red."""
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8)
    img.reshape(-1, 3)[:changed, 0] ^= 1
    Image.fromarray(img).save(path)
    return path


# ----------------------------------------------------------------------------------------------- built cases
def normal_cases(d: Path) -> list[Path]:
    """Normals differing only (OBJ ``vn``, PLY ``nx ny nz``); ``v//vn`` corners (mm drops them), none, too few."""
    return [
        obj(d / "up.obj", normals=UP),
        obj(d / "tilted.obj", normals=TILTED),
        obj(d / "indexed.obj", normals=TILTED, normal_index=True),
        obj(d / "none.obj"),
        obj(d / "three.obj", normals=UP[:3]),
        ply(d / "up.ply", normals=UP),
        ply(d / "tilted.ply", normals=TILTED),
    ]


def colour_cases(d: Path) -> list[Path]:
    """Per-vertex colours (OBJ ``v x y z r g b`` scaled by 255, PLY ``uchar``): differing, partial, absent."""
    grey = [(0.5, 0.5, 0.5)] * 4
    return [
        obj(d / "grey.obj", colors=grey),
        obj(d / "red.obj", colors=[(1.0, 0.0, 0.0), *grey[1:]]),
        obj(d / "almost.obj", colors=[(0.501, 0.5, 0.5), *grey[1:]]),  # the same byte after the scaling
        obj(d / "partial.obj", colors=[None, (1.0, 0.0, 0.0), None, (0.5, 0.5, 0.5)]),
        obj(d / "none.obj"),
        ply(d / "grey.ply", colors=[(128, 128, 128)] * 4),
        ply(d / "red.ply", colors=[(255, 0, 0)] + [(128, 128, 128)] * 3),
    ]


def uv_list_cases(d: Path) -> list[Path]:
    """UV lists of different lengths, per corner and per position (OBJ ``vt`` without indices, PLY texture_u/v)."""
    return [
        obj(d / "four.obj", uvs=UV4, corner_uvs=PER_CORNER),
        obj(d / "five.obj", uvs=[*UV4, (0.5, 0.5)], corner_uvs=PER_CORNER),  # an unused fifth UV
        obj(d / "six.obj", uvs=[(0.5, 0.5), *UV4, (0.2, 0.2)], corner_uvs=[(1, 2, 3), (1, 3, 4)]),
        obj(d / "moved.obj", uvs=[*UV4[:3], (0.0, 0.9)], corner_uvs=PER_CORNER),
        obj(d / "split.obj", uvs=[*UV4, (0.0, 0.0)], corner_uvs=[(0, 1, 2), (4, 2, 3)]),  # a seam
        obj(d / "shuffled.obj", uvs=UV4, corner_uvs=PER_CORNER, tris=[(2, 0, 1), (3, 0, 2)]),
        obj(d / "vertex_uv.obj", uvs=UV4),  # no index: mm takes them per position
        obj(d / "vertex_uv3.obj", uvs=UV4[:3]),  # no index, fewer than positions: no UVs for equ
        obj(d / "no_uv.obj"),
        obj(d / "moved_vertex.obj", verts=[*QUAD[:3], (0.0, 2.0, 0.0)], uvs=UV4, corner_uvs=PER_CORNER),
        ply(d / "vertex_uv.ply", uvs=UV4),
        ply(d / "moved.ply", uvs=[*UV4[:3], (0.0, 0.9)]),
    ]


MATERIALS = {
    "t": "newmtl m0\nmap_Kd t.png\n",
    "t_copy": "newmtl m0\nmap_Kd t_copy.png\n",
    "t3": "newmtl m0\nmap_Kd t3.png\n",
    "wide": "newmtl m0\nmap_Kd wide.png\n",
    "nomap": "newmtl m0\nKd 1 1 1\n",
    "two": "newmtl m0\nmap_Kd t.png\nnewmtl m1\nmap_Kd t3.png\n",
    "lost": "newmtl m0\nmap_Kd gone.png\n",
}
"""The MTL files of :func:`texture_cases`, by name."""


def texture_cases(d: Path) -> list[Path]:
    """Maps equal (a copy), differing in 3 texels, in size, missing on either side (a material without a map, a model
    without MTL, a map file that does not exist), two materials, a map without UVs, an MTL file that does not exist.
    The images are ``d / "t.png"`` (8x6), ``t_copy.png``, ``t3.png`` (3 texels changed) and ``wide.png`` (9x6)."""
    png(d / "t.png", (8, 6))
    png(d / "t_copy.png", (8, 6))
    png(d / "t3.png", (8, 6), changed=3)
    png(d / "wide.png", (9, 6))
    for name, text in MATERIALS.items():
        (d / f"{name}.mtl").write_text(text)
    files = [obj(d / f"{name}.obj", uvs=UV4, corner_uvs=PER_CORNER, mtl=f"{name}.mtl") for name in MATERIALS]
    files.append(obj(d / "bare.obj", uvs=UV4, corner_uvs=PER_CORNER))
    files.append(obj(d / "geometry.obj", mtl="t.mtl"))  # a map but no UVs: mm still reads the map
    files.append(obj(d / "no_mtl_file.obj", mtl="absent.mtl"))
    return files


def given_maps(d: Path) -> list[tuple[Path | None, Path | None]]:
    """Maps given on the command line (``--inputMapA/B``) for ``bare.obj`` against ``t.obj`` (:func:`texture_cases`)."""
    return [(d / "t3.png", None), (d / "t.png", d / "wide.png"), (None, d / "t.png")]
