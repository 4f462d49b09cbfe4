"""Textures and materials are read as mmetric reads them, and a requested colour figure is never dropped silently."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric.data.mesh_file import MeshFileError
from torchmeshmetric.data.obj import parse_mtl
from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh, read_texture

OBJ = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl skin\nf 1/1 2/2 3/3\n"


def _png(img: np.ndarray, *, palette: np.ndarray | None = None, bit_depth: int = 8) -> bytes:
    """A minimal PNG encoder (any colour type and depth), so that the tests control every byte of the file."""
    h, w = img.shape[:2]
    ctype = 3 if palette is not None else 0 if img.ndim == 2 else {2: 4, 3: 2, 4: 6}[img.shape[2]]
    raw = (img.astype(">u2").view(np.uint8) if bit_depth == 16 else img.astype(np.uint8)).reshape(h, -1)
    data = b"".join(b"\x00" + raw[r].tobytes() for r in range(h))

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    out = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bit_depth, ctype, 0, 0, 0))
    if palette is not None:
        out += chunk(b"PLTE", palette.astype(np.uint8).tobytes())
    return out + chunk(b"IDAT", zlib.compress(data)) + chunk(b"IEND", b"")


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), alpha=st.booleans())
def test_16_bit_texture_is_its_high_byte(tmp_path_factory, seed: int, alpha: bool) -> None:
    """stb_image (mmetric) keeps ``value >> 8`` of a 16-bit image; failed before for greyscale-like clipping."""
    rng = np.random.default_rng(seed)
    img16 = rng.integers(0, 65536, (5, 7, 4 if alpha else 3), dtype=np.uint16)
    folder = tmp_path_factory.mktemp("tex")
    (folder / "t16.png").write_bytes(_png(img16, bit_depth=16))
    (folder / "t8.png").write_bytes(_png((img16 >> 8).astype(np.uint8)))
    ours = read_texture(folder / "t16.png")
    np.testing.assert_array_equal(ours, (img16[..., :3] >> 8).astype(np.uint8))
    np.testing.assert_array_equal(ours, read_texture(folder / "t8.png"))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), colours=st.integers(1, 256))
def test_paletted_texture_is_expanded_through_its_palette(tmp_path_factory, seed: int, colours: int) -> None:
    rng = np.random.default_rng(seed)
    palette = rng.integers(0, 256, (colours, 3))
    index = rng.integers(0, colours, (6, 4))
    p = tmp_path_factory.mktemp("pal") / "p.png"
    p.write_bytes(_png(index, palette=palette))
    np.testing.assert_array_equal(read_texture(p), palette[index].astype(np.uint8))


@pytest.mark.parametrize("bit_depth", [8, 16])
@pytest.mark.parametrize("alpha", [False, True])
def test_greyscale_texture_is_refused(tmp_path: Path, bit_depth: int, alpha: bool) -> None:
    """mmetric reads three bytes per texel of a 1- or 2-channel map: its colours would be meaningless."""
    img = np.zeros((3, 3, 2) if alpha else (3, 3), dtype=np.uint16)
    (tmp_path / "g.png").write_bytes(_png(img, bit_depth=bit_depth))
    with pytest.raises(MeshFileError, match=r"g\.png' is a greyscale image .*save the texture as RGB"):
        read_texture(tmp_path / "g.png")


def _textured(folder: Path, mtl: str, tex_name: str | None = "tex.png", obj: str = OBJ) -> Path:
    (folder / "m.obj").write_text(obj)
    (folder / "m.mtl").write_text(mtl)
    if tex_name is not None:
        img = np.arange(2 * 2 * 3, dtype=np.uint8).reshape(2, 2, 3) * 10
        (folder / tex_name).write_bytes(_png(img))
    return folder / "m.obj"


@pytest.mark.parametrize(
    ("line", "name"),
    [
        ("map_Kd my texture.png", "my texture.png"),
        ("map_Kd  -s 1 1 1 -o 0.5 my texture.png", "my texture.png"),
        ("map_Kd -blendu off -clamp on -mm 0 1 tex.png", "tex.png"),
        ("map_Kd -o 0.5 0.25 tex.png", "tex.png"),
        ("  map_Kd tex.png  ", "tex.png"),
    ],
)
def test_map_kd_name_is_everything_after_the_keyword_and_options(tmp_path: Path, line: str, name: str) -> None:
    """Failed before: a name with a space was cut at the space (and options were taken as the name)."""
    obj = _textured(tmp_path, f"newmtl skin\nKd 1 1 1\n{line}\n", name)
    assert parse_mtl(tmp_path / "m.mtl")[0].map_kd == name
    t = load_textured_mesh(obj)
    assert t.texture is not None and t.texture.shape == (2, 2, 3) and t.has_color


def test_missing_mtl_is_refused_naming_obj_line_and_file(tmp_path: Path) -> None:
    """Failed before: the colour figures were dropped with exit 0 and no word (mmetric prints 'Error: can't open
    file' and goes on without colour; a requested figure must not vanish silently)."""
    (tmp_path / "m.obj").write_text(OBJ)
    with pytest.raises(MeshFileError, match=r"m\.obj:1: 'mtllib m\.mtl' names a material file that does not exist"):
        load_textured_mesh(tmp_path / "m.obj")
    img = np.zeros((2, 2, 3), np.uint8)
    (tmp_path / "given.png").write_bytes(_png(img))
    assert load_textured_mesh(tmp_path / "m.obj", tmp_path / "given.png").has_color  # an explicit texture is enough
    (tmp_path / "plain.obj").write_text(OBJ.replace("/1", "").replace("/2", "").replace("/3", ""))
    assert not load_textured_mesh(tmp_path / "plain.obj").has_color  # no UVs: nothing is looked up


def test_missing_texture_names_the_mtl_line(tmp_path: Path) -> None:
    obj = _textured(tmp_path, "newmtl skin\n\nmap_Kd gone.png\n", None)
    with pytest.raises(MeshFileError, match=r"map_Kd at .*m\.mtl:3\).*gone\.png' not found"):
        load_textured_mesh(obj)


def test_faces_using_two_textures_are_refused(tmp_path: Path) -> None:
    """Failed before: the first map_Kd coloured every face (mmetric uses one map per material)."""
    obj = OBJ + "v 2 0 0\nusemtl hair\nf 2/2 4/1 3/3\n"
    path = _textured(tmp_path, "newmtl skin\nmap_Kd tex.png\nnewmtl hair\nmap_Kd hair.png\n", "tex.png", obj)
    (tmp_path / "hair.png").write_bytes((tmp_path / "tex.png").read_bytes())
    with pytest.raises(MeshFileError, match=r"materials with different textures \('skin' \(tex\.png\), 'hair'"):
        load_textured_mesh(path)
    # two materials naming the same texture are one texture
    path = _textured(tmp_path, "newmtl skin\nmap_Kd tex.png\nnewmtl hair\nmap_Kd tex.png\n", "tex.png", obj)
    assert load_textured_mesh(path).has_color


def test_material_without_map_gives_no_colour(tmp_path: Path) -> None:
    """A material with only a Kd colour has no texture (mmetric: no map, no colour figures); documented."""
    assert not load_textured_mesh(_textured(tmp_path, "newmtl skin\nKd 1 0 0\n", None)).has_color


def test_material_numbering_follows_mmetric(tmp_path: Path) -> None:
    """Faces before any ``usemtl`` take the first material; an unknown name keeps the material in force."""
    mtl = "newmtl skin\nmap_Kd tex.png\nnewmtl hair\nmap_Kd hair.png\n"
    obj = OBJ.replace("usemtl skin\n", "") + "usemtl nonexistent\nf 1/1 2/2 3/3\n"
    assert load_textured_mesh(_textured(tmp_path, mtl, "tex.png", obj)).has_color  # all faces: 'skin'
    obj = OBJ + "usemtl nonexistent\nf 1/1 2/2 3/3\nusemtl hair\nf 1/1 2/2 3/3\n"
    with pytest.raises(MeshFileError, match="different textures"):
        load_textured_mesh(_textured(tmp_path, mtl, "tex.png", obj))


def test_mmetric_test_meshes(tmp_path: Path) -> None:
    from tests.mpeg.conftest import MM_TESTS

    folder = MM_TESTS
    t = load_textured_mesh(folder / "plane.obj")
    assert t.has_color and t.texture is not None and t.uvs is not None
    with pytest.raises(MeshFileError, match=r"different textures \('material0000' \(plane\.png\), 'material0001'"):
        load_textured_mesh(folder / "plane_multi_map.obj")  # mmetric: one map per material; we: one per mesh


@pytest.mark.parametrize("kind", ["rgb16", "rgba16", "palette", "rgba8"])
def test_texture_colours_equal_mm_sample(tmp_path: Path, kind: str) -> None:
    """The outside oracle: ``mm sample --mode grid`` on a textured mesh with a 16-bit, paletted or RGBA map gives
    the colours we sample from the map as ``read_texture`` reads it (mmetric writes them rounded to 8 bits)."""
    import subprocess

    from tests.mpeg.conftest import MM
    from torchmeshmetric.mpeg import grid_sample

    if not MM.is_file():
        pytest.skip("mmetric's mm binary absent (../shared/tools/mmetric/mm)")
    rng = np.random.default_rng(7)
    if kind == "rgb16":
        png = _png(rng.integers(0, 65536, (8, 8, 3), dtype=np.uint16), bit_depth=16)
    elif kind == "rgba16":
        png = _png(rng.integers(0, 65536, (8, 8, 4), dtype=np.uint16), bit_depth=16)
    elif kind == "palette":
        png = _png(rng.integers(0, 16, (8, 8)), palette=rng.integers(0, 256, (16, 3)))
    else:
        png = _png(rng.integers(0, 256, (8, 8, 4)))
    (tmp_path / "tex.png").write_bytes(png)
    obj = "v 0 0 0\nv 1 0 0\nv 1 1 0.2\nv 0 1 0.1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
    (tmp_path / "m.obj").write_text(obj)
    args = ["sample", "--mode", "grid", "--gridSize", "32", "--useNormal", "--bilinear", "--hideProgress"]
    args += ["-i", str(tmp_path / "m.obj"), "-m", str(tmp_path / "tex.png"), "-o", str(tmp_path / "s.ply")]
    subprocess.run([str(MM), *args], capture_output=True, text=True, timeout=300, check=True)
    with open(tmp_path / "s.ply") as fh:
        for line in fh:
            if line.startswith("end_header"):
                break
        theirs = np.loadtxt(fh, dtype=np.float64, ndmin=2)
    t = load_textured_mesh(tmp_path / "m.obj", tmp_path / "tex.png")
    ours = grid_sample(t.mesh, 32, texture=t.texture, uvs=t.uvs, bilinear=True)
    assert ours.colors is not None and ours.num_points == theirs.shape[0]
    np.testing.assert_array_equal(np.floor(ours.colors.numpy() + 0.5), theirs[:, 6:9])


def test_obj_vertex_colours_equal_mm_sample(tmp_path: Path) -> None:
    """OBJ ``v x y z r g b`` colours anywhere in [0, 1] (not only k / 255): mmetric rounds ``value * 255`` when it
    reads them, and its grid samples interpolate the rounded colours; failed before (unrounded colours)."""
    import subprocess

    import trimesh

    from tests.mpeg.conftest import MM
    from torchmeshmetric.mpeg import grid_sample

    if not MM.is_file():
        pytest.skip("mmetric's mm binary absent (../shared/tools/mmetric/mm)")
    m = trimesh.creation.icosphere(2)
    c = np.random.default_rng(4).random((len(m.vertices), 3))
    lines = [
        f"v {x:.9g} {y:.9g} {z:.9g} {r:.9g} {g:.9g} {b:.9g}" for (x, y, z), (r, g, b) in zip(m.vertices, c, strict=True)
    ]
    lines += [f"f {a + 1} {b + 1} {d + 1}" for a, b, d in m.faces]
    (tmp_path / "c.obj").write_text("\n".join(lines) + "\n")
    args = ["sample", "--mode", "grid", "--gridSize", "48", "--useNormal", "--hideProgress"]
    args += ["-i", str(tmp_path / "c.obj"), "-o", str(tmp_path / "s.ply")]
    subprocess.run([str(MM), *args], capture_output=True, text=True, timeout=300, check=True)
    with open(tmp_path / "s.ply") as fh:
        for line in fh:
            if line.startswith("end_header"):
                break
        theirs = np.loadtxt(fh, dtype=np.float64, ndmin=2)
    t = load_textured_mesh(tmp_path / "c.obj")
    ours = grid_sample(t.mesh, 48, colors=t.colors)
    assert ours.colors is not None and ours.num_points == theirs.shape[0]
    np.testing.assert_array_equal(np.floor(ours.colors.numpy() + 0.5), theirs[:, 6:9])
