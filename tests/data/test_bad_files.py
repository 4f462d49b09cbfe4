"""Mesh files are checked against what they declare and what their format allows; errors name file and line."""

import re
import struct

import numpy as np
import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric.data import MeshFileError, load_mesh

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


def _write(tmp_path, name, content):
    p = tmp_path / name
    p.write_bytes(content.encode() if isinstance(content, str) else content)
    return p


def _assert_load_error_names_file(path, message):
    with pytest.raises(MeshFileError, match=message) as info:
        load_mesh(path)
    assert str(path) in str(info.value)


# ----------------------------------------------------------------------------------------------- OBJ
@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"line 1: vertex 0 has 2 coordinate\(s\)"),
        (TRI + "v 1 1\nf 1 2 3\n", r"line 4: vertex 3 has 2 coordinate\(s\)"),
        ("v 0 0 0 1 2\n" + TRI + "f 1 2 3\n", r"line 1: vertex 0 has 5 coordinate"),
        (TRI + "f 0 1 2\n", r"line 4: face index 0 is invalid \(OBJ indices start at 1"),
        (TRI + "f 1 2 4\n", r"face 0: vertex index 4 is out of range \(the file has 3 vertices\)"),
        (TRI + "f 1 2 3\nf 1 2 30\n", r"face 1: vertex index 30 is out of range"),
        (TRI + "f -1 -2 -4\n", r"line 4: face index -4 counts back past the first vertex \(3 vertices"),
        ("v 0 0 0\nf -1 -2 -3\nv 1 0 0\nv 0 1 0\n", r"line 2: face index -2 counts back past the first"),
        (TRI + "f 1 2 x\n", r"line 4: face corner 'x' is not a vertex index"),
        ("v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"line 1: vertex coordinates '0 0 zero' are not numbers"),
        ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"vertex 0 \(line 1\) has non-finite coordinates"),
        (TRI + "v inf 0 0\nf 1 2 3\n", r"vertex 3 \(line 4\) has non-finite coordinates"),
        (TRI + "f 1 2 3 1\n", r"line 4 has a face with 4 corners; expected triangles"),
        (TRI, r"has no faces \(3 vertices\)"),
        ("hello world\n" + TRI + "f 1 2 3\n", r"is not a mesh file \(line 1 starts with 'hello'"),
        ("# only a comment\n", r"is not a mesh file \(no OBJ statement"),
        (TRI + "f 1 2 3\n\x00\x01\x02", r"is not a mesh file \(binary data at line 5"),
        ("v 0 0 1e39\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"coordinates up to 1e\+39, beyond the range of torch.float32"),
        # found by review: Python's float and int (the line-by-line pass) read "1_0" as 10
        ("v 1_0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"line 1: vertex coordinates '1_0 0 0' are not numbers"),
        (TRI + "f 1 2 0_3\n", r"line 4: face corner '0_3' is not a vertex index"),
    ],
)
def test_malformed_obj_names_file_line_and_problem(tmp_path, content, message):
    _assert_load_error_names_file(_write(tmp_path, "frame.obj", content), message)


def test_float64_holds_what_float32_cannot(tmp_path):
    p = _write(tmp_path, "big.obj", "v 0 0 1e39\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert load_mesh(p, dtype=torch.float64).verts[0, 2].item() == 1e39


@settings(max_examples=30, deadline=None)
@given(
    data=st.data(),
    num_verts=st.integers(3, 12),
)
def test_negative_obj_indices_count_back_from_the_last_vertex_defined(tmp_path_factory, data, num_verts):
    """A face written with relative (negative) indices loads as the same face written with absolute ones, also
    when faces and vertices interleave."""
    rng = np.random.default_rng(num_verts)
    verts = rng.normal(size=(num_verts, 3))
    faces = data.draw(st.lists(st.lists(st.integers(0, num_verts - 1), min_size=3, max_size=3), min_size=1))
    lines_abs, lines_rel, defined = [], [], 0
    for face in faces:
        while defined <= max(face):  # define vertices up to the largest index the face uses
            line = "v " + " ".join(repr(float(x)) for x in verts[defined])
            lines_abs.append(line)
            lines_rel.append(line)
            defined += 1
        lines_abs.append("f " + " ".join(str(i + 1) for i in face))
        lines_rel.append("f " + " ".join(f"{i - defined}/1/1" if i % 2 else str(i - defined) for i in face))
    folder = tmp_path_factory.mktemp("neg")
    a = load_mesh(_write(folder, "a.obj", "\n".join(lines_abs)), dtype=torch.float64)
    b = load_mesh(_write(folder, "b.obj", "\n".join(lines_rel)), dtype=torch.float64)
    assert a.faces.tolist() == faces
    assert b.faces.tolist() == faces
    assert torch.equal(a.verts, torch.tensor(verts[:defined]))


@pytest.mark.parametrize(
    "content",
    [
        b"# auteur: Fran\xe7ois, mod\xe8le \xe9t\xe9 2024\n" + TRI.encode() + b"f 1 2 3\n",  # Latin-1 comment
        "# caf\u00e9 \u2014 UTF-8\n".encode() + TRI.encode() + b"f 1 2 3\n",
        b"\xef\xbb\xbf# BOM\r\n" + TRI.replace("\n", "\r\n").encode() + b"f 1 2 3\r\n",
        b"mtllib sc\xe8ne.mtl\no Obj\xe9t\nusemtl m\n"
        + TRI.encode()
        + b"vt 0 0\nvn 0 0 1\ns off\nf 1/1/1 2/1/1 3/1/1\n",
        TRI.encode() + b"f 1 2 \\\n 3\n",  # line continuation
        b"v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n",  # w coordinate
        b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n",  # vertex colours
    ],
)
def test_valid_obj_variants_load(tmp_path, content):
    m = load_mesh(_write(tmp_path, "ok.obj", content), dtype=torch.float64)
    assert m.faces.tolist() == [[0, 1, 2]]
    assert m.verts.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]


def test_obj_keeps_every_vertex_in_file_order(tmp_path):
    # unreferenced and duplicate vertices survive (a registration refers to vertices by index)
    content = "v 5 5 5\n" + TRI + "v 0 0 0\no second\nf 2 3 4\nf 5 3 4\n"
    m = load_mesh(_write(tmp_path, "order.obj", content), dtype=torch.float64)
    assert m.verts.tolist() == [[5, 5, 5], [0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0]]
    assert m.faces.tolist() == [[1, 2, 3], [4, 2, 3]]


# ----------------------------------------------------------------------------------------------- OFF
def _off(sphere):
    return sphere.export(file_type="off")


@settings(max_examples=25, deadline=None)
@given(cut=st.floats(0.05, 0.995))
def test_truncated_off_is_refused_naming_the_declared_counts(tmp_path_factory, cut):
    sphere = trimesh.creation.icosphere(subdivisions=1)
    text = _off(sphere)
    lines = text.splitlines()
    kept = "\n".join(lines[: max(2, int(len(lines) * cut))]) + "\n"
    p = _write(tmp_path_factory.mktemp("off"), "cut.off", kept)
    with pytest.raises(MeshFileError, match=r"is truncated: its header \(line 2\) declares 42 vertices and 80 faces"):
        load_mesh(p)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", r"line 6: face 0 has vertex indices \[0, 1, 3\] outside"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", r"outside \[0, 2\] \(OFF is 0-based\)"),
        ("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", r"line 4: vertex 1 has 2 coordinate"),
        ("OFF\n3 1 0\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n", r"vertex 1 \(line 4\) has non-finite coordinates"),
        ("OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n", r"line 7 has a face with 4 corners"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", r"face 0 declares 3 corners but lists 2"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n", r"line 7: more lines than the header"),
        ("OFF\nthree 1 0\n", r"line 2: expected the counts"),
        ("NOT OFF\n3 1 0\n", r"is not a mesh file \(an OFF file starts with 'OFF', found 'NOT'\)"),
        ("OFF\n", r"ends after its 'OFF' line"),
    ],
)
def test_malformed_off_names_file_line_and_problem(tmp_path, content, message):
    _assert_load_error_names_file(_write(tmp_path, "frame.off", content), message)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        # a 4-value vertex line made up for a 2-value one: the total matched
        ("OFF\n3 1 0\n0 0 0 0\n1 0\n0 1 0\n3 0 1 2\n", r"line 4: vertex 1 has 2 coordinate\(s\); expected 3"),
        # a 5-value face line made up for a 3-value one: 2 triangles loaded
        ("OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2 3\n1 3 2\n", r"line 8 has a face with 1 corners"),
        # Python's float and int read "1_0" as 10
        ("OFF\n3 1 0\n0 0 0\n1_0 0 0\n0 1 0\n3 0 1 2\n", r"line 4: vertex 1 coordinates are not numbers"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 0_2\n", r"line 6: face 0 is not a list of vertex indices"),
        ("OFF\n1_0 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", r"line 2: expected the counts"),
    ],
)
def test_off_fast_pass_refuses_what_the_line_by_line_pass_refuses(tmp_path, content, message):
    """Found by review: the vectorised pass checked only the total count of values, so the first two loaded as
    other geometry (after a comment line, the line-by-line pass refused them); and that pass, with Python's float
    and int, read "1_0" as 10. Both passes now refuse all of them, with the same message."""
    _assert_load_error_names_file(_write(tmp_path, "frame.off", content), message)
    plain = str(_load_error(_write(tmp_path, "frame.off", content)))
    # a comment line sends the file to the line-by-line pass; its lines are one further down
    slow = str(_load_error(_write(tmp_path, "frame.off", content.replace("OFF\n", "OFF\n# a comment\n", 1))))
    assert re.sub(r"line (\d+)", lambda m: f"line {int(m[1]) - 1}", slow) == plain


def _load_error(path):
    with pytest.raises(MeshFileError) as info:
        load_mesh(path)
    return info.value


def test_truncated_off_does_not_count_face_lines_as_vertices(tmp_path):
    # found by review: a header declaring 3e9 vertices over 3 vertex lines and 1 face line said "the file holds
    # 4 vertices and 0 faces"
    p = _write(tmp_path, "cut.off", "OFF\n3000000000 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    _assert_load_error_names_file(
        p, r"declares 3000000000 vertices and 1 faces, the file holds 4 lines after it, fewer than its vertices"
    )


@pytest.mark.parametrize(
    "content",
    [
        "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
        "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",  # counts on the OFF line
        "# c\nOFF\n# comment\n\n3 1 0\n0 0 0  # v0\n1 0 0\n0 1 0\n3 0 1 2 255 0 0\n",  # comments, face colour
        "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n",
    ],
)
def test_valid_off_variants_load(tmp_path, content):
    m = load_mesh(_write(tmp_path, "ok.off", content), dtype=torch.float64)
    assert m.faces.tolist() == [[0, 1, 2]] and m.verts.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]


def test_latin1_comment_in_off_and_ply_header_loads(tmp_path):
    off = "OFF\n# mod\xe8le\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n".encode("latin-1")
    assert load_mesh(_write(tmp_path, "a.off", off)).num_faces == 1
    ply = trimesh.creation.icosphere(subdivisions=1).export(file_type="ply")
    ply = ply.replace(b"end_header", b"comment mod\xe8le \xe9t\xe9\nend_header", 1)
    assert load_mesh(_write(tmp_path, "a.ply", ply)).num_faces == 80


# ----------------------------------------------------------------------------------------------- PLY / STL
@pytest.mark.parametrize("encoding", ["ascii", "binary"])
@pytest.mark.parametrize("cut", [0.7, 0.9, 0.99])
def test_truncated_ply_is_refused(tmp_path, encoding, cut):
    data = trimesh.creation.icosphere(subdivisions=1).export(file_type="ply", encoding=encoding)
    p = _write(tmp_path, "cut.ply", data[: int(len(data) * cut)])
    with pytest.raises(MeshFileError, match=r"cut\.ply.*(declares 42 vertex, 80 face elements|declares 80 face)"):
        load_mesh(p)


def test_ply_with_polygons_is_refused_not_triangulated(tmp_path):
    header = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    header += "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
    p = _write(tmp_path, "quad.ply", header + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    with pytest.raises(MeshFileError, match=r"quad\.ply' line 14 has a face with 4 corners; expected triangles"):
        load_mesh(p)


_XYZ = "property float x\nproperty float y\nproperty float z\n"
_RGB = "property uchar red\nproperty uchar green\nproperty uchar blue\n"


def _ply(body, nv=3, nf=1, props=_XYZ, fmt="ascii"):
    header = f"ply\nformat {fmt} 1.0\nelement vertex {nv}\n{props}"
    header += f"element face {nf}\nproperty list uchar int vertex_indices\nend_header\n"
    return header.encode("latin-1") + (body.encode() if isinstance(body, str) else body)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        # found by review: each line's values were not counted, only their total, so these loaded as other geometry
        (
            _ply("0 0 0 0\n1 0\n0 1 0\n3 0 1 2\n"),
            r"line 10: vertex 0 has 4 value\(s\); its header declares 3 \(x y z\)",
        ),
        (
            _ply("0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2 3\n1 3 2\n", nv=4, nf=2),
            r"line 14: face 0 declares 3 corners but lists 4",
        ),
        # found by review: values were cast to the declared type unchecked (300 as uchar is 44, -1 is 255, 0.7 as
        # int is 0, a face index 2.5 is 2)
        (
            _ply("0 0 0 300 0 0\n1 0 0 0 0 0\n0 1 0 0 0 0\n3 0 1 2\n", props=_XYZ + _RGB),
            r"line 13: vertex 0 property 'red' is 300, which its declared type uchar cannot hold \(outside \[0, 255\]",
        ),
        (
            _ply("0 0 0 0 0 0\n1 0 0 0 -1 0\n0 1 0 0 0 0\n3 0 1 2\n", props=_XYZ + _RGB),
            r"line 14: vertex 1 property 'green' is -1, which its declared type uchar cannot hold",
        ),
        (
            _ply("0 0 0 0\n1 0 0 0.7\n0 1 0 0\n3 0 1 2\n", props=_XYZ + "property int quality\n"),
            r"line 12: vertex 1 property 'quality' is 0.7, which its declared type int cannot hold \(not an integer\)",
        ),
        (_ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n"), r"line 13: face 0 vertex index is 2.5, which its declared type int"),
        (_ply("0 0 0\n1 0 1e39\n0 1 0\n3 0 1 2\n"), r"line 11: vertex 1 property 'z' is 1e39, .* \(beyond the range"),
        # found by review: a property named twice gave numpy's ValueError (binary) or the last column (ASCII)
        (
            _ply("0 0 0 0\n1 0 0 1\n0 1 0 2\n3 0 1 2\n", props=_XYZ + "property float x\n"),
            r"line 7: property 'x' is declared twice in its element \(first at line 4\)",
        ),
        (
            _ply(
                struct.pack("<12f", *range(12)) + struct.pack("<B3i", 3, 0, 1, 2),
                props=_XYZ + "property float x\n",
                fmt="binary_little_endian",
            ),
            r"line 7: property 'x' is declared twice in its element \(first at line 4\)",
        ),
        # found by review: "²" (Latin-1 \xb2) passed str.isdigit(), then int() raised a bare ValueError
        (
            _ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", nv="\xb2"),
            r"line 3: 'element vertex \xb2' is not 'element NAME COUNT'",
        ),
        # review G, finding 4: lines beyond the declared elements were dropped by trimesh (a second face, a junk line)
        (
            _ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n"),
            r"line 14: more lines than the header declares \(3 vertex, 1 face elements\)",
        ),
        (
            _ply("0 0 0\n1 0 0\n0 1 0\n3 1 2 0\n9 9 9\n"),
            r"line 14: more lines than the header declares \(3 vertex, 1 face elements\)",
        ),
        # review G, finding 10: a value that is no number gave numpy's "unmatched data", with no line
        (_ply("0 0 0\n1 0 0\n0 1 x\n3 0 1 2\n"), r"line 12: vertex 2 holds 'x', which is not a number"),
        (_ply("0 0 0\n0x10 0 0\n0 1 0\n3 0 1 2\n"), r"line 11: vertex 1 holds '0x10', which is not a number"),
        (_ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 two\n"), r"line 13: face 0 holds 'two', which is not a number"),
        (_ply("0 0 0\ncomment a b\n1 0 0\n0 1 0\n3 0 1 2\n"), r"line 11: vertex 1 holds 'comment', which is not"),
        # review G, finding 10: two vertex elements were read as one (the second count), blamed on the faces
        (
            _ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", props=_XYZ + "element vertex 3\n" + _XYZ),
            r"line 7: element 'vertex' is declared twice \(first at line 3\)",
        ),
        # review G, finding 10: "format ascii 2.0" was read as PLY 1.0 without a word
        (
            _ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").replace(b"1.0", b"2.0"),
            r"line 2: 'format ascii 2.0' is not 'format ascii 1.0', .* \(PLY 1.0 is the only version\)",
        ),
        (
            _ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").replace(b"format ascii 1.0\n", b""),
            r"has a PLY header without a 'format' line",
        ),
        # review G, finding 11: a quad beside a 2- or 1-corner face made as many triangles as declared faces, and
        # loaded as a fanned quad (ASCII and binary, plain or with an extra face property)
        (_ply("0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 3 2\n2 0 1\n", nv=4, nf=2), r"line 14 has a face with 4 corners"),
        (_ply("0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 3 2\n1 0\n", nv=4, nf=2), r"line 14 has a face with 4 corners"),
        (
            _ply(
                struct.pack("<12f", *range(12)) + struct.pack("<B4i", 4, 0, 1, 3, 2) + struct.pack("<B2i", 2, 0, 1),
                nv=4,
                nf=2,
                fmt="binary_little_endian",
            ),
            r"frame\.ply' face 0 has 4 corners; expected triangles",
        ),
        (  # a triangle first: the quad after it is found at the triangles' stride
            _ply(
                struct.pack("<12f", *range(12))
                + struct.pack("<B3i", 3, 0, 1, 2)
                + struct.pack("<B4i", 4, 0, 1, 3, 2)
                + struct.pack("<B2i", 2, 0, 1),
                nv=4,
                nf=3,
                fmt="binary_little_endian",
            ),
            r"frame\.ply' face 1 has 4 corners; expected triangles",
        ),
        (  # not plain (a face property besides the list): through trimesh, whose lists are checked
            _ply("0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 3 2 7\n2 0 1 8\n", nv=4, nf=2).replace(
                b"vertex_indices\n", b"vertex_indices\nproperty uchar q\n"
            ),
            r"frame\.ply' face 0 has 4 corners; expected triangles",
        ),
    ],
)
def test_ply_values_and_header_are_checked(tmp_path, content, message):
    _assert_load_error_names_file(_write(tmp_path, "frame.ply", content), message)


def test_ply_trailing_blank_lines_and_a_byte_order_mark_are_accepted(tmp_path):
    body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    assert load_mesh(_write(tmp_path, "blank.ply", _ply(body + "\n  \n\t\n"))).faces.tolist() == [[0, 1, 2]]
    # review G, finding 10: refused as "a PLY file starts with 'ply'", while OBJ, OFF and trimesh read past the mark
    bom = load_mesh(_write(tmp_path, "bom.ply", b"\xef\xbb\xbf" + _ply(body)))
    assert bom.verts.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]] and bom.faces.tolist() == [[0, 1, 2]]
    not_plain = _ply(body).replace(b"element face", b"element edge 0\nproperty int a\nelement face")
    assert load_mesh(_write(tmp_path, "bom2.ply", b"\xef\xbb\xbf" + not_plain)).faces.tolist() == [[0, 1, 2]]


def test_end_header_in_a_ply_comment_is_no_end_of_header(tmp_path):
    # found by review: the first "end_header" in the file, a comment's, was taken for the end of the header
    data = _ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").replace(b"ply\n", b"ply\ncomment edited before end_header\n", 1)
    assert load_mesh(_write(tmp_path, "c.ply", data)).faces.tolist() == [[0, 1, 2]]
    trimesh_path = data.replace(b"element face", b"element edge 0\nproperty int a\nelement face")  # not plain
    assert load_mesh(_write(tmp_path, "t.ply", trimesh_path)).faces.tolist() == [[0, 1, 2]]


def test_a_gltf_that_is_not_json_is_named_not_a_model_gltf(tmp_path):
    # review G, finding 10: trimesh's fallback said "FileNotFoundError: model.gltf", a file the user never gave
    p = _write(tmp_path, "bad.gltf", "{not json")
    with pytest.raises(MeshFileError) as info:
        load_mesh(p)
    assert str(info.value) == (
        f"path: '{p}' is not a mesh file (a .gltf file is JSON; line 1 column 2: Expecting property name enclosed in "
        "double quotes)"
    )
    box = trimesh.creation.box()  # a .gltf that is JSON, its buffer embedded, still loads through trimesh
    good = _write(tmp_path, "box.gltf", box.export(file_type="gltf", embed_buffers=True)["model.gltf"])
    assert load_mesh(good, dtype=torch.float64).num_faces == 12


@pytest.mark.parametrize("missing", [1, 20, 50, 3000])
def test_truncated_binary_stl_is_refused(tmp_path, missing):
    data = trimesh.creation.icosphere(subdivisions=1).export(file_type="stl")
    p = _write(tmp_path, "cut.stl", data[:-missing])
    with pytest.raises(MeshFileError, match=r"or is truncated: .* declares 80 triangles"):
        load_mesh(p)


def test_binary_stl_with_a_wrong_count_is_refused(tmp_path):
    data = bytearray(trimesh.creation.icosphere(subdivisions=1).export(file_type="stl"))
    data[80:84] = struct.pack("<I", 81)
    with pytest.raises(MeshFileError, match="declares 81 triangles"):
        load_mesh(_write(tmp_path, "count.stl", bytes(data)))


# ----------------------------------------------------------------------------------------------- garbage
@settings(max_examples=20, deadline=None)
@given(
    payload=st.binary(min_size=200, max_size=2000).filter(lambda b: any(c < 9 or 13 < c < 32 for c in b)),
    suffix=st.sampled_from([".obj", ".off", ".ply", ".stl", ".glb"]),
)
def test_binary_garbage_is_not_a_mesh_file(tmp_path_factory, payload, suffix):
    p = _write(tmp_path_factory.mktemp("garbage"), f"noise{suffix}", payload)
    with pytest.raises(MeshFileError, match="is not a mesh file") as info:
        load_mesh(p)
    assert "charset" not in str(info.value) and "module" not in str(info.value)


def test_a_directory_given_as_a_frame_is_reported_as_a_directory(tmp_path):
    # issue 29: it was reported as "does not exist", by every reader and by a list of frames
    from torchmeshmetric.data import list_frames, read_mesh_arrays
    from torchmeshmetric.mpeg import load_textured_mesh

    folder = tmp_path / "frame_0001.obj"
    folder.mkdir()
    for read in (load_mesh, read_mesh_arrays, load_textured_mesh):
        with pytest.raises(MeshFileError, match=r"frame_0001\.obj' is a directory, not a mesh file"):
            read(folder)
    with pytest.raises(MeshFileError, match=r"paths: '.*frame_0001\.obj' is a directory, not a mesh file"):
        list_frames([folder])
