"""One reader per format: every path (load_mesh, load_sequence, load_textured_mesh) reads a file as one geometry,
with the same checks and the same file:line messages; the vectorised passes equal the statement-by-statement ones."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.data.test_bad_files import TRI
from torchmeshmetric.data.io import load_mesh, read_mesh_arrays
from torchmeshmetric.data.mesh_file import MeshFileError
from torchmeshmetric.data.obj import _parse_fast, _parse_slow, parse_obj
from torchmeshmetric.data.off import _parse_off_slow
from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh

_FORMS = ("{v}", "{v}/{t}", "{v}/{t}/{n}", "{v}//{n}")


def _write(folder: Path, name: str, content: str | bytes) -> Path:
    p = folder / name
    p.write_bytes(content.encode() if isinstance(content, str) else content)
    return p


def _random_obj(data: st.DataObject, num_verts: int, *, uv: bool) -> tuple[str, str, np.ndarray, list[list[int]]]:
    """The same mesh written twice, with absolute and with mixed absolute/relative (negative) indices, vertices
    and faces interleaved (each face after the vertices it uses)."""
    rng = np.random.default_rng(num_verts)
    verts = rng.normal(size=(num_verts, 3)) * 10.0 ** rng.integers(-3, 4)
    faces = data.draw(st.lists(st.lists(st.integers(0, num_verts - 1), min_size=3, max_size=3), min_size=1))
    form = data.draw(st.sampled_from(_FORMS[1:3] if uv else _FORMS))
    rel = data.draw(st.lists(st.booleans(), min_size=3 * len(faces), max_size=3 * len(faces)))
    absolute, relative, defined = [], [], 0
    for j, face in enumerate(faces):
        while defined <= max(face):
            line = "v " + " ".join(repr(float(x)) for x in verts[defined])
            vt = f"vt {defined / num_verts!r} {1 - defined / num_verts!r}"
            absolute += [line, vt]
            relative += [line, vt]
            defined += 1
        absolute.append("f " + " ".join(form.format(v=i + 1, t=i + 1, n=1) for i in face))
        corners = []
        for k, i in enumerate(face):
            r = rel[3 * j + k]
            corners.append(form.format(v=i - defined if r else i + 1, t=i - defined if r else i + 1, n=1))
        relative.append("f " + " ".join(corners))
    relative.insert(0, "vn 0 0 1")
    absolute.insert(0, "vn 0 0 1")
    return "\n".join(absolute) + "\n", "\n".join(relative) + "\n", verts[:defined], faces


@settings(max_examples=40, deadline=None)
@given(data=st.data(), num_verts=st.integers(3, 15), uv=st.booleans())
def test_negative_and_positive_indices_give_one_mesh_on_every_path(tmp_path_factory, data, num_verts, uv) -> None:
    """Failed before: the MPEG path counted a negative index back from the file's last vertex, ``load_mesh`` from
    the last one defined before the line (two meshes from one file)."""
    text_abs, text_rel, verts, faces = _random_obj(data, num_verts, uv=uv)
    folder = tmp_path_factory.mktemp("obj")
    a, b = _write(folder, "abs.obj", text_abs), _write(folder, "rel.obj", text_rel)
    for p in (a, b):
        m = load_mesh(p, dtype=torch.float64)
        t = load_textured_mesh(p)
        assert m.faces.tolist() == faces
        assert t.mesh.faces.tolist() == faces
        assert torch.equal(m.verts, torch.from_numpy(verts))
        assert torch.equal(t.mesh.verts, torch.from_numpy(verts).float())
        if uv:
            assert t.uvs is not None
            expected = np.stack([np.arange(len(verts)) / num_verts, 1 - np.arange(len(verts)) / num_verts], 1)
            np.testing.assert_array_equal(t.uvs.numpy(), expected[np.array(faces)].astype(np.float32))
    # an outside oracle: trimesh reads the absolute file as the same mesh (no UVs: trimesh then keeps the order)
    plain = _write(folder, "plain.obj", "".join(ln + "\n" for ln in text_abs.splitlines() if not ln.startswith("vt")))
    plain.write_text(re.sub(r"/\d*/?\d*", "", plain.read_text()))
    ours = load_mesh(plain, dtype=torch.float64)
    theirs = trimesh.load(plain, process=False, maintain_order=True)
    np.testing.assert_array_equal(ours.faces.numpy(), theirs.faces)
    np.testing.assert_array_equal(ours.verts.numpy()[: len(theirs.vertices)], theirs.vertices)


def _decorate(data: st.DataObject, text: str) -> bytes:
    """Equivalent spellings of one file: CRLF, tabs, comments, blank lines, groups and materials."""
    lines = text.splitlines()
    out = []
    for ln in lines:
        if data.draw(st.booleans()):
            out.append(data.draw(st.sampled_from(["", "# a comment", "g part", "usemtl m1", "usemtl m2", "s off"])))
        if data.draw(st.booleans()) and ln.startswith(("v ", "f ")):
            ln = ln.replace(" ", "\t", 1)
        out.append(ln + data.draw(st.sampled_from(["", "  ", " # trailing comment"])))
    eol = data.draw(st.sampled_from(["\n", "\r\n"]))
    return (eol.join(out) + data.draw(st.sampled_from(["", eol]))).encode()


@settings(max_examples=60, deadline=None)
@given(data=st.data(), num_verts=st.integers(3, 12), uvs=st.booleans(), normals=st.booleans())
def test_vectorised_pass_equals_statement_by_statement_pass(data, num_verts, uvs, normals) -> None:
    _, text, _, _ = _random_obj(data, num_verts, uv=data.draw(st.booleans()))
    raw = _decorate(data, text)
    fast = _parse_fast(raw, uvs, normals)
    slow = _parse_slow(Path("x.obj"), raw, uvs, normals)
    whole = parse_obj(Path("x.obj"), raw, uvs=uvs, normals=normals)
    names = ("verts", "vert_lines", "uvs", "uv_lines", "corners", "corner_uvs", "face_sizes", "face_lines")
    names += ("normals", "normal_lines", "color_rows")
    for d in [whole] + ([fast] if fast is not None else []):
        for name in names:
            np.testing.assert_array_equal(getattr(d, name), getattr(slow, name), err_msg=name)
        np.testing.assert_array_equal(d.face_materials, slow.face_materials)
        assert d.materials == slow.materials and d.mtllibs == slow.mtllibs
        assert d.normal_indexed == slow.normal_indexed
    assert len(slow.normals) == (1 if normals else 0)  # the one "vn 0 0 1" line
    assert slow.normal_indexed == bool(re.search(r"/-?\d*/", text))  # the v/vt/vn and v//vn forms


def test_normals_and_partial_colours_in_both_passes() -> None:
    """``vn`` lines, corners naming normals, and the colour rows of the vertices that have one (mmetric's list)."""
    text = "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 0 0.5 1\nvn 0 0 1\nvn 0 1 0\n"
    for faces, indexed in (("f 1 2 3\n", False), ("f 1//1 2//2 3//1\n", True), ("f 1/1/1 2/1/2 3/1/1\n", True)):
        raw = (text + ("vt 0 0\n" if "/1/" in faces else "") + faces).encode()
        for d in (_parse_fast(raw, True, True), _parse_slow(Path("x.obj"), raw, True, True)):
            assert d is not None and d.normal_indexed == indexed
            assert d.normals.tolist() == [[0, 0, 1], [0, 1, 0]] and d.normal_lines.tolist() == [4, 5]
            assert d.vert_colors is None and d.color_rows.tolist() == [[1, 0, 0], [0, 0.5, 1]]
    with pytest.raises(MeshFileError, match=r"line 2: normal 0 has 2 value\(s\)"):
        parse_obj(Path("x.obj"), TRI.replace("v 1 0 0", "vn 0 1\nv 1 0 0").encode() + b"f 1 2 3\n", normals=True)
    with pytest.raises(MeshFileError, match=r"normal 0 \(line 1\) is not finite"):
        parse_obj(Path("x.obj"), b"vn nan 0 1\n" + TRI.encode() + b"f 1 2 3\n", normals=True)


@settings(max_examples=30, deadline=None)
@given(values=st.lists(st.floats(-1e300, 1e300, allow_nan=False), min_size=3, max_size=60))
def test_vectorised_numbers_are_pythons_floats(values) -> None:
    """Every coordinate is the correctly rounded double Python's ``float`` gives (the fast pass must not differ)."""
    values = values[: len(values) // 3 * 3]
    fmt = ["{!r}", "{:.9g}", "{:.6f}", "{:.3e}"]
    for f in fmt:
        text = "".join("v " + " ".join(f.format(x) for x in values[i : i + 3]) + "\n" for i in range(0, len(values), 3))
        d = parse_obj(Path("x.obj"), (text + "f 1 1 1\n").encode())
        expected = np.array([float(t) for ln in text.splitlines() for t in ln.split()[1:]]).reshape(-1, 3)
        np.testing.assert_array_equal(d.verts, expected)


# ----------------------------------------------------------------------------------------------- the same errors
_BAD_OBJ = [
    ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"line 1: vertex 0 has 2 coordinate\(s\)"),
    (TRI + "f 0 1 2\n", r"line 4: face index 0 is invalid"),
    (TRI + "f 1 2 4\n", r"line 4: face 0: vertex index 4 is out of range \(the file has 3 vertices\)"),
    (TRI + "f -1 -2 -4\n", r"line 4: face index -4 counts back past the first vertex"),
    ("v 0 0 0\nf -1 -2 -3\nv 1 0 0\nv 0 1 0\n", r"line 2: face index -2 counts back past the first"),
    (TRI + "f 1 2 x\n", r"line 4: face corner 'x' is not a vertex index"),
    ("v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"line 1: vertex coordinates '0 0 zero' are not numbers"),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"vertex 0 \(line 1\) has non-finite coordinates"),
    (TRI + "v inf 0 0\nf 1 2 3\n", r"vertex 3 \(line 4\) has non-finite coordinates"),
    (TRI + "f 1 2\n", r"line 4 has a face with 2 corners"),
    (TRI, r"has no faces \(3 vertices\)"),
    ("hello world\n" + TRI + "f 1 2 3\n", r"is not a mesh file \(line 1 starts with 'hello'"),
    ("# only a comment\n", r"is not a mesh file \(no OBJ statement"),
    (TRI + "f 1 2 3\n\x00\x01\x02", r"is not a mesh file \(binary data at line 5"),
    ("v 0 0 1e39\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"line 1: vertex 0 has coordinates up to 1e\+39, beyond the range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 -2e39\nf 1 2 3\n", r"line 4: vertex 3 has coordinates up to 2e\+39"),
]


@pytest.mark.parametrize(("content", "message"), _BAD_OBJ)
def test_every_path_gives_the_same_file_line_error(tmp_path: Path, content: str, message: str) -> None:
    """Failed before: the MPEG path said ``verts: expected finite values`` (no file) for 1e39, and its own words
    for the rest."""
    p = _write(tmp_path, "frame.obj", content)
    errors = []
    for load in (load_mesh, load_textured_mesh):
        with pytest.raises(MeshFileError, match=message) as info:
            load(p)
        assert str(p) in str(info.value)
        errors.append(str(info.value).split(";")[0])
    assert errors[0] == errors[1]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (TRI + "vt nan nan\nf 1/1 2/1 3/1\n", r"texture coordinate 0 \(line 4\) is not finite: \[nan, nan\]"),
        (TRI + "vt 0 0\nvt inf 0\nf 1/1 2/2 3/1\n", r"texture coordinate 1 \(line 5\) is not finite"),
        (TRI + "vt 0 0\nf 1/1 2/2 3/1\n", r"line 5: texture index 2 is out of range \(the file has 1 'vt' lines\)"),
        (TRI + "vt 0 0\nf 1/0 2/1 3/1\n", r"line 5: face texture index 0 is invalid"),
        (TRI + "vt 0 0\nf 1/-2 2/1 3/1\n", r"line 5: face texture index -2 counts back past the first 'vt'"),
        (TRI + "vt 0\nf 1/1 2/1 3/1\n", r"line 4: texture coordinate 0 has 1 value\(s\); expected 'vt u v'"),
        (TRI + "vt 0 a\nf 1/1 2/1 3/1\n", r"line 4: texture coordinates '0 a' are not numbers"),
        (TRI + "vt 0 0\nf 1/1 2/1 3/1\nf 1 2 3\n", r"frame.obj:6: this face has no texture index"),
        # found by review: "uvs: expected finite values" (no file, no line) and a numpy overflow warning
        (
            TRI + "vt 0 0\nvt 1e300 0\nf 1/1 2/2 3/1\n",
            r"line 5: texture coordinate 1 has values up to 1e\+300, beyond the range of torch.float32 .*; mmetric",
        ),
    ],
)
def test_bad_uvs_are_refused_with_file_and_line(tmp_path: Path, content: str, message: str) -> None:
    """Failed before: ``vt nan nan`` was accepted (meaningless colours); a face without UVs dropped them all."""
    p = _write(tmp_path, "frame.obj", content)
    with pytest.raises(MeshFileError, match=message) as info:
        load_textured_mesh(p)
    assert str(p) in str(info.value)
    assert load_mesh(p).num_faces >= 1  # geometry alone does not need the UVs


def test_polygons_are_fanned_on_the_mpeg_path_and_refused_by_load_mesh(tmp_path: Path) -> None:
    p = _write(tmp_path, "quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 2 0\nf 1 2 3 4 5\n")
    assert load_textured_mesh(p).mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [0, 3, 4]]  # as mmetric does
    with pytest.raises(MeshFileError, match="line 6 has a face with 5 corners; expected triangles"):
        load_mesh(p)


def test_obj_vertex_colours_round_as_mmetric(tmp_path: Path) -> None:
    """mmetric stores ``roundf((float)value * 255)``; failed before (0.5019 gave 127.99 instead of 128), and
    0.0019607842 (whose float32 product is 0.49999997) gave 1, not 0: ``floor(x + 0.5)`` in float32 rounds it up
    (review P; mm reads that pair's colours as equal)."""
    from decimal import ROUND_HALF_UP, Decimal

    values = [0.5019, 0.001, 0.999, 1 / 255, 0.5 / 255, 1.5 / 255, 0.0019607841968536377, 2.5 / 255]
    lines = [f"v {i} 0 0 {values[i]} {values[-1 - i]} 0.25" for i in range(len(values))]
    p = _write(tmp_path, "c.obj", "\n".join(lines) + "\nf 1 2 3\nf 4 5 6\nf 6 7 8\n")
    c = load_textured_mesh(p).colors
    assert c is not None
    products = np.array(values, np.float32) * np.float32(255)  # (float)value * 255, in float32 as mmetric
    # roundf: halves away from zero, exactly (Decimal's ROUND_HALF_UP rounds the exact binary value)
    expected = [float(Decimal(float(x)).quantize(Decimal(1), rounding=ROUND_HALF_UP)) for x in products]
    assert c[:, 0].tolist() == expected
    assert expected[6] == 0.0 and products[6] == np.float32(0.49999997)
    assert c[:, 2].tolist() == [64.0] * len(values)


# ----------------------------------------------------------------------------------------------- OFF and PLY
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), sub=st.integers(0, 2))
def test_off_fast_pass_equals_slow_pass_and_trimesh(tmp_path_factory, seed, sub) -> None:
    rng = np.random.default_rng(seed)
    m = trimesh.creation.icosphere(subdivisions=sub)
    m.vertices = m.vertices * 10.0 ** rng.integers(-5, 5) + rng.normal(size=m.vertices.shape)
    p = tmp_path_factory.mktemp("off") / "m.off"
    p.write_text(m.export(file_type="off"))
    ours = load_mesh(p, dtype=torch.float64)
    v, f = _parse_off_slow(p, p.read_bytes())
    np.testing.assert_array_equal(ours.verts.numpy(), v)
    np.testing.assert_array_equal(ours.faces.numpy(), f)
    np.testing.assert_array_equal(ours.faces.numpy(), m.faces)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), encoding=st.sampled_from(["binary", "ascii"]), colour=st.booleans())
def test_ply_reader_equals_trimesh(tmp_path_factory, seed, encoding, colour) -> None:
    rng = np.random.default_rng(seed)
    m = trimesh.creation.icosphere(subdivisions=int(rng.integers(0, 3)))
    m.vertices = m.vertices + rng.normal(size=m.vertices.shape)
    if colour:
        m.visual.vertex_colors = rng.integers(0, 256, (len(m.vertices), 4), dtype=np.uint8)
    p = tmp_path_factory.mktemp("ply") / "m.ply"
    p.write_bytes(m.export(file_type="ply", encoding=encoding))
    verts, faces, colors = read_mesh_arrays(p)
    theirs = trimesh.load(p, process=False, maintain_order=True)
    np.testing.assert_array_equal(verts, theirs.vertices)
    np.testing.assert_array_equal(faces, theirs.faces)
    if colour:
        assert colors is not None
        np.testing.assert_array_equal(colors, np.asarray(theirs.visual.vertex_colors)[:, :3])
        t = load_textured_mesh(p)
        assert t.colors is not None and torch.equal(t.colors, torch.from_numpy(colors).float())
    np.testing.assert_array_equal(load_mesh(p, dtype=torch.float64).verts.numpy(), theirs.vertices)


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_normals_and_texture_coordinates(tmp_path: Path, encoding: str) -> None:
    """``nx ny nz`` and ``texture_u texture_v`` (mmetric's per-vertex properties) come back as their types hold them."""
    from torchmeshmetric.data.ply import read_plain_ply

    rng = np.random.default_rng(1)
    xyz, nrm, uv = rng.normal(size=(4, 3)), rng.normal(size=(4, 3)), rng.random((4, 2))
    props = [("float", "x"), ("float", "y"), ("float", "z"), ("double", "nx"), ("double", "ny"), ("double", "nz")]
    props += [("float", "texture_u"), ("float", "texture_v")]
    head = f"ply\nformat {encoding} 1.0\nelement vertex 4\n" + "".join(f"property {t} {n}\n" for t, n in props)
    head += "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    if encoding == "ascii":
        rows = [" ".join(repr(float(x)) for x in (*a, *b, *c)) for a, b, c in zip(xyz, nrm, uv, strict=True)]
        body = ("\n".join(rows + [f"3 {a} {b} {c}" for a, b, c in faces]) + "\n").encode()
    else:
        o = "<" if encoding.endswith("little_endian") else ">"
        vdt = np.dtype([(n, o + ("f4" if t == "float" else "f8")) for t, n in props])
        vtab = np.empty(4, dtype=vdt)
        for k, (_, n) in enumerate(props):
            vtab[n] = np.concatenate([xyz, nrm, uv], axis=1)[:, k]
        ftab = np.empty(2, dtype=[("n", "u1"), ("i", o + "i4", (3,))])
        ftab["n"], ftab["i"] = 3, faces
        body = vtab.tobytes() + ftab.tobytes()
    path = tmp_path / "m.ply"
    path.write_bytes(head.encode() + body)
    read = read_plain_ply(path)
    assert read is not None and read.colors is None
    np.testing.assert_array_equal(read.normals, nrm)  # double properties: exact
    np.testing.assert_array_equal(read.uvs, uv.astype(np.float32))  # float properties: float32 values
    np.testing.assert_array_equal(read.faces, faces)


@settings(max_examples=30, deadline=None)
@given(values=st.lists(st.integers(-(10**16), 10**16), min_size=3, max_size=30), sign=st.sampled_from(["", "+"]))
def test_integer_coordinates_are_read_exactly(values, sign) -> None:
    """The integer shortcut gives Python's floats, also for values too large for it (the float parser then)."""
    values = values[: len(values) // 3 * 3]
    text = "".join(
        "v " + " ".join(f"{sign if x >= 0 else ''}{x}" for x in values[i : i + 3]) + "\n"
        for i in range(0, len(values), 3)
    )
    d = parse_obj(Path("x.obj"), (text + "f 1 1 1\n").encode())
    np.testing.assert_array_equal(d.verts, np.array([float(x) for x in values]).reshape(-1, 3))
    z = parse_obj(Path("x.obj"), b"v -0 0 -00\nf 1 1 1\n").verts
    assert np.signbit(z).tolist() == [[True, False, True]]  # as Python's float("-0")


@settings(max_examples=60, deadline=None)
@given(
    lines=st.lists(st.lists(st.sampled_from(["0", "-1.5", "1e3", "x"]), max_size=6), min_size=1, max_size=30),
    gaps=st.sampled_from([" ", "  ", "\t", " \r"]),
    chunk=st.integers(1, 64),
)
def test_values_per_line_counts_each_lines_values(lines, gaps, chunk) -> None:
    """The per-line count the OFF and ASCII PLY fast passes check, in runs of lines of any size."""
    from torchmeshmetric.data.mesh_file import values_per_line

    text = "".join(gaps.join(ln) + gaps + "\n" for ln in lines).encode()
    buf = np.frombuffer(text, dtype=np.uint8)
    nl = np.flatnonzero(buf == 10)
    counts = values_per_line(buf, np.concatenate(([0], nl[:-1] + 1)), chunk=chunk)
    assert counts.tolist() == [len(ln) for ln in lines]
