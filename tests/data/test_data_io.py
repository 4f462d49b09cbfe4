import os
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import Mesh, as_mesh
from torchmeshmetric.data import MeshFileError, list_frames, load_mesh, load_sequence, natural_key, save_mesh

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _sphere() -> Mesh:
    return as_mesh(trimesh.creation.icosphere(subdivisions=2))


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".off", ".stl", ".glb"])
def test_round_trip(tmp_path: Path, suffix: str) -> None:
    m = _sphere()
    p = save_mesh(m, tmp_path / f"s{suffix}")
    back = load_mesh(p, dtype=torch.float64)
    if suffix == ".stl":  # STL stores triangle soups: 3 vertices per face, same triangles
        assert back.num_faces == m.num_faces
        torch.testing.assert_close(back.verts[back.faces], m.verts[m.faces].to(back.verts), atol=1e-6, rtol=0)
    else:
        assert torch.equal(back.faces, m.faces)
        tol = 0 if suffix in (".obj", ".off", ".ply") else 1e-6  # bit for bit; GLB stores float32 (this mesh: float64)
        torch.testing.assert_close(back.verts, m.verts, atol=tol, rtol=0)


@pytest.mark.parametrize("suffix", [".off", ".ply"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_off_and_ply_round_trip_bit_for_bit(tmp_path: Path, dtype: torch.dtype, suffix: str) -> None:
    """Found by review: OFF was written by trimesh with 10 decimals, so coordinates of ~3e-11 were saved as zeros
    and float32 meshes did not round-trip exactly; PLY, written by trimesh too, stored float64 meshes as float32 (up
    to 2.6e-8 lost on a unit sphere)."""
    rng = np.random.default_rng(0)
    scale = np.repeat([1e-11, 3e-11, 1.0, 1e30], 300)[:, None]
    verts = torch.from_numpy(rng.normal(size=(1200, 3)) * scale).to(dtype)
    verts[0] = torch.tensor([-0.0, 0.1, 1 / 3], dtype=dtype)
    faces = torch.from_numpy(rng.integers(0, 1200, size=(500, 3)))
    back = load_mesh(save_mesh(Mesh(verts, faces), tmp_path / f"m{suffix}"), dtype=dtype)
    bits = torch.int32 if dtype == torch.float32 else torch.int64
    assert torch.equal(back.verts.view(bits), verts.view(bits))  # bit for bit: -0.0 too
    assert torch.equal(back.faces, faces)
    tiny = Mesh(torch.tensor([[3e-11, 0, 0], [0, 3e-11, 0], [0, 0, 3e-11]], dtype=dtype), faces[:1] % 3)
    assert load_mesh(save_mesh(tiny, tmp_path / "tiny.off"), dtype=dtype).verts.abs().max() > 0


@pytest.mark.parametrize(
    ("dtype", "suffix"),
    # STL and GLB store float32: float64's largest cannot be written (tested below)
    [(torch.float32, s) for s in (".off", ".obj", ".ply", ".stl", ".glb")]
    + [(torch.float64, s) for s in (".off", ".obj", ".ply")],
)
def test_the_largest_finite_coordinate_round_trips(tmp_path: Path, dtype: torch.dtype, suffix: str) -> None:
    # review G, finding 8: float32's largest written as OFF ("3.4028235e+38", its shortest text) was refused on
    # loading as "beyond the range of torch.float32": the parsed float64 is above it, yet rounds back to it
    big = torch.finfo(dtype).max
    verts = torch.tensor([[big, 0, 0], [0, -big, 0], [0, 0, 1]], dtype=dtype)
    back = load_mesh(save_mesh(Mesh(verts, torch.tensor([[0, 1, 2]])), tmp_path / f"m{suffix}"), dtype=dtype)
    corners = back.verts[back.faces[0]]  # STL: a soup, the same triangle
    bits = torch.int32 if dtype == torch.float32 else torch.int64
    assert torch.equal(corners.view(bits), verts.view(bits))


def test_float32_text_within_half_a_unit_of_the_largest_loads_as_it(tmp_path: Path) -> None:
    from torchmeshmetric.data.mesh_file import MeshFileError

    # numpy's str of float32's largest, as another writer gives it; rounded, it is that largest, not inf
    (tmp_path / "max.obj").write_text("v 3.4028235e+38 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n")
    assert load_mesh(tmp_path / "max.obj").verts[0, 0].item() == torch.finfo(torch.float32).max
    (tmp_path / "over.obj").write_text("v 3.4028236e+38 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n")  # rounds to inf
    with pytest.raises(MeshFileError, match=r"line 1: vertex 0 has coordinates up to 3.4028236e\+38, beyond the range"):
        load_mesh(tmp_path / "over.obj")
    assert load_mesh(tmp_path / "over.obj", dtype=torch.float64).verts[0, 0].item() == 3.4028236e38


@pytest.mark.parametrize("suffix", [".stl", ".glb"])
def test_a_float64_coordinate_beyond_float32_is_not_written_as_inf(tmp_path: Path, suffix: str) -> None:
    # review G, finding 8: STL and GLB store float32, and a float64 mesh's 1e39 was written as inf
    from torchmeshmetric.data.mesh_file import MeshFileError

    verts = torch.tensor([[0, 0, 0], [1, 0, 0], [0, -1e39, 0]], dtype=torch.float64)
    kind = suffix[1:].upper()
    with pytest.raises(MeshFileError) as info:
        save_mesh(Mesh(verts, torch.tensor([[0, 1, 2]])), tmp_path / f"m{suffix}")
    assert str(info.value) == (
        f"path: mesh file '{tmp_path / f'm{suffix}'}' vertex 2 has coordinates up to 1e+39, beyond the range of "
        f"torch.float32 (max 3.4028235e+38; 1 such vertices); cannot write it as {kind}, which stores float32: save "
        "as .ply, .obj or .off (float64), or scale it"
    )
    assert not (tmp_path / f"m{suffix}").exists()


def test_vertex_order_and_duplicates_survive(tmp_path: Path) -> None:
    verts = torch.tensor([[0.0, 1, 0], [0, 0, 0], [1, 0, 0], [0, 0, 0]], dtype=torch.float64)
    faces = torch.tensor([[1, 2, 0], [3, 2, 0]])
    for suffix in (".obj", ".ply", ".off"):
        back = load_mesh(save_mesh(Mesh(verts, faces), tmp_path / f"d{suffix}"), dtype=torch.float64)
        assert torch.equal(back.verts, verts) and torch.equal(back.faces, faces)


def test_natural_order(tmp_path: Path) -> None:
    for n in (10, 2, 1, 33):
        (tmp_path / f"frame{n}.obj").write_text(f"v 0 0 {n}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "notes.txt").write_text("not a mesh")
    names = [p.name for p in list_frames(tmp_path)]
    assert names == ["frame1.obj", "frame2.obj", "frame10.obj", "frame33.obj"]
    assert [p.name for p in list_frames(str(tmp_path / "frame*.obj"))] == names
    seq = load_sequence(tmp_path)
    assert [float(m.verts[0, 2]) for m in seq] == [1.0, 2.0, 10.0, 33.0]
    explicit = [tmp_path / "frame33.obj", tmp_path / "frame1.obj"]
    assert list_frames(explicit) == explicit  # an explicit list keeps its order
    assert sorted(["a10b2", "a2b10", "a2b9"], key=natural_key) == ["a2b9", "a2b10", "a10b2"]


def test_a_broken_link_among_the_frames_is_refused(tmp_path: Path) -> None:
    """Found by review: a folder's dangling symlink was dropped silently (f0, f1 -> /nonexistent, f2 listed as
    [f0, f2]), so every frame after the hole took the number of the one before; a glob dropped it too."""
    for n in (0, 2):
        (tmp_path / f"f{n}.obj").write_text(TRI)
    (tmp_path / "f1.obj").symlink_to(tmp_path / "nonexistent.obj")
    for paths in (tmp_path, str(tmp_path / "f*.obj"), [tmp_path / "f0.obj", tmp_path / "f1.obj"]):
        with pytest.raises(MeshFileError, match=r"frame '.*f1\.obj' is a broken symbolic link \(to '.*nonexistent"):
            list_frames(paths)
    (tmp_path / "f1.obj").unlink()
    (tmp_path / "f1.obj").symlink_to(tmp_path / "f2.obj")  # a link to a file is a frame like any other
    assert [q.name for q in list_frames(tmp_path)] == ["f0.obj", "f1.obj", "f2.obj"]


def test_a_folder_leaves_hidden_files_out_as_a_glob_does(tmp_path: Path) -> None:
    # found by review: a folder listed ".hidden.obj" (an editor's or a sync tool's copy) where "*.obj" does not
    for name in ("f0.obj", "f1.obj", ".hidden.obj"):
        (tmp_path / name).write_text(TRI)
    (tmp_path / ".gone.obj").symlink_to(tmp_path / "nonexistent.obj")  # hidden: not a frame, even broken
    assert [q.name for q in list_frames(tmp_path)] == ["f0.obj", "f1.obj"]
    assert list_frames(tmp_path) == list_frames(str(tmp_path / "*.obj"))


def test_missing_and_empty_inputs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(MeshFileError, match="does not exist"):
        load_mesh(tmp_path / "nope.obj")
    with pytest.raises(MeshFileError, match="does not exist"):
        list_frames(tmp_path / "nope")
    with pytest.raises(MeshFileError, match="no mesh files"):
        list_frames(tmp_path)
    with pytest.raises(MeshFileError, match="matches no files"):
        list_frames(str(tmp_path / "*.ply"))
    with pytest.raises(MeshFileError, match="empty"):
        list_frames([])
    # An empty name (an unset variable) is not the current folder, even where that folder holds meshes.
    (tmp_path / "frame0.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    monkeypatch.chdir(tmp_path)
    for empty in ("", " "):
        with pytest.raises(
            MeshFileError, match=f"paths: expected a directory, a glob pattern or a mesh file, found {empty!r}"
        ):
            list_frames(empty)
    (tmp_path / "empty.obj").write_text("")
    with pytest.raises(MeshFileError, match=r"empty.obj.*empty"):
        load_mesh(tmp_path / "empty.obj")
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\n")
    with pytest.raises(MeshFileError, match=r"points\.obj"):
        load_mesh(tmp_path / "points.obj")


def test_non_triangle_and_corrupt(tmp_path: Path) -> None:
    (tmp_path / "quad.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    with pytest.raises(MeshFileError, match=r"quad.obj.*4 corners"):
        load_mesh(tmp_path / "quad.obj")
    header = b"ply\nformat binary_little_endian 1.0\nelement vertex 1000\nend_header\n"
    (tmp_path / "bad.ply").write_bytes(header + b"\x00\x01")
    with pytest.raises(MeshFileError, match=r"bad\.ply"):
        load_mesh(tmp_path / "bad.ply")
    (tmp_path / "bad.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(MeshFileError, match=r"bad\.glb"):
        load_mesh(tmp_path / "bad.glb")
    (tmp_path / "x.xyz").write_text(TRI)
    with pytest.raises(MeshFileError, match="unsupported suffix"):
        load_mesh(tmp_path / "x.xyz")


def test_save_refuses_overwrite_and_is_atomic(tmp_path: Path) -> None:
    m = _sphere()
    p = tmp_path / "m.ply"
    save_mesh(m, p)
    before = p.read_bytes()
    with pytest.raises(FileExistsError, match="overwrite=True"):
        save_mesh(m, p)
    assert p.read_bytes() == before
    small = as_mesh(trimesh.creation.box())
    save_mesh(small, p, overwrite=True)
    assert load_mesh(p).num_faces == 12
    assert sorted(os.listdir(tmp_path)) == ["m.ply"]  # no temporary file left behind
    with pytest.raises(MeshFileError, match="does not exist"):
        save_mesh(m, tmp_path / "missing_dir" / "m.obj")
    with pytest.raises(MeshFileError, match="unsupported suffix"):
        save_mesh(m, tmp_path / "m.txt")


@pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.complex64, torch.int32, "float32", None])
def test_a_dtype_other_than_float32_or_float64_is_refused_naming_dtype(tmp_path: Path, dtype: object) -> None:
    # review G, finding 7: load_mesh and Mesh.to built float16, bfloat16 and complex meshes (validate=False), and
    # raised torch's own TypeError for int32 or "float32"
    from torchmeshmetric import DTypeError
    from torchmeshmetric.data.sequence import iter_sequence

    p = save_mesh(as_mesh(trimesh.creation.icosphere(subdivisions=1)), tmp_path / "m.ply")
    found = "str 'float32' (pass torch.float32)" if dtype == "float32" else repr(dtype)
    message = f"dtype: expected torch.float32 or torch.float64, found {found}"
    mesh = load_mesh(p)
    calls = [lambda: load_mesh(p, dtype=dtype), lambda: load_sequence(tmp_path, dtype=dtype)]  # type: ignore[arg-type]
    calls.append(lambda: iter_sequence(tmp_path, dtype=dtype))  # type: ignore[arg-type]
    if dtype is not None:  # None: Mesh.to and as_mesh keep the dtype
        calls += [lambda: mesh.to(dtype=dtype), lambda: as_mesh(mesh, dtype=dtype)]  # type: ignore[arg-type]
        calls.append(lambda: as_mesh((mesh.verts, mesh.faces), dtype=dtype))  # type: ignore[arg-type]
    for call in calls:
        with pytest.raises(DTypeError) as info:
            call()
        assert str(info.value) == message
    assert mesh.to(dtype=None).dtype == torch.float32


def test_float32_and_float64_are_the_dtypes_accepted(tmp_path: Path) -> None:
    p = save_mesh(as_mesh(trimesh.creation.icosphere(subdivisions=1)), tmp_path / "m.ply")
    for dtype in (torch.float32, torch.float64):
        assert load_mesh(p, dtype=dtype).dtype == dtype and load_sequence(tmp_path, dtype=dtype)[0].dtype == dtype
        assert load_mesh(p).to(dtype=dtype).dtype == dtype


def test_save_mesh_takes_every_mesh_form_the_library_takes(tmp_path: Path) -> None:
    # review G, finding 12: save_mesh((v, f), p) raised "mesh: expected a Mesh, found tuple", though the library
    # says every function that takes a mesh takes a (verts, faces) tuple and a trimesh.Trimesh
    m = _sphere()
    forms = {
        "tensors": (m.verts, m.faces),
        "arrays": (m.verts.numpy(), m.faces.numpy().astype(np.uint32)),
        "trimesh": m.to_trimesh(),
        "mesh": m,
    }
    for name, form in forms.items():
        back = load_mesh(save_mesh(form, tmp_path / f"{name}.ply"), dtype=torch.float64)  # type: ignore[arg-type]
        assert torch.equal(back.verts, m.verts) and torch.equal(back.faces, m.faces), name
    with pytest.raises(TypeError) as info:
        save_mesh("m.ply", tmp_path / "str.ply")  # type: ignore[arg-type]
    assert str(info.value) == "mesh: expected a Mesh, a (verts, faces) tuple or a trimesh.Trimesh, found str"


def test_stl_keeps_no_vertex_list_a_mesh_comes_back_as_a_triangle_soup(tmp_path: Path) -> None:
    # As save_mesh and docs/data.md say: 320 faces over 162 shared vertices come back with 3 vertices per face
    m = _sphere()
    back = load_mesh(save_mesh(m, tmp_path / "s.stl"), dtype=torch.float64)
    assert (m.num_verts, back.num_verts, back.num_faces) == (162, 960, 320)
    assert torch.equal(back.faces, torch.arange(960).reshape(320, 3))
