"""Files the CLI writes: report sets all or nothing, normal permissions, a file in the way of a folder is named."""

import os
import stat

import pytest

from tests.cli.cli_helpers import write_frames
from tests.test_atomic import DiskFull
from torchmeshmetric.cli import main

SMALL_DEMO = ["--frames", "3", "--resolution", "24", "--target", "0.5"]


def _evaluate(tmp_path, sequence, *extra):
    orig, simp = sequence
    return main(["evaluate", "--original", str(orig), "--simplified", str(simp), *extra])


@pytest.mark.parametrize("fail_at", [1, 2, 3])
def test_full_disk_while_writing_a_report_leaves_no_file_and_a_rerun_works(
    capsys, tmp_path, sequence, known_registration, monkeypatch, fail_at
):
    out = tmp_path / "out"
    out.mkdir()
    with monkeypatch.context() as m:
        DiskFull(m, fail_at)
        assert _evaluate(tmp_path, sequence, "--out", str(out / "report.json")) == 1
    err = capsys.readouterr().err
    assert "could not write the report: No space left on device; none of its files was written" in err
    assert os.listdir(out) == []
    assert _evaluate(tmp_path, sequence, "--out", str(out / "report.json")) == 0
    assert sorted(os.listdir(out)) == ["report.csv", "report.json", "report.md"]


def test_full_disk_while_overwriting_keeps_the_previous_reports(
    capsys, tmp_path, sequence, known_registration, monkeypatch
):
    out = tmp_path / "report.json"
    for name in ("report.json", "report.md", "report.csv"):
        (tmp_path / name).write_text(f"previous {name}")
    with monkeypatch.context() as m:
        DiskFull(m, 3)
        assert _evaluate(tmp_path, sequence, "--out", str(out), "--overwrite") == 1
    for name in ("report.json", "report.md", "report.csv"):
        assert (tmp_path / name).read_text() == f"previous {name}"
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]


def test_full_disk_in_simplify_writes_no_frame_and_removes_the_folder_it_created(
    capsys, tmp_path, known_registration, monkeypatch
):
    frames = write_frames(tmp_path / "orig", 1)
    out = tmp_path / "new" / "simplified"
    with monkeypatch.context() as m:
        DiskFull(m, 3)
        assert main(["simplify", "--input", str(frames), "--output", str(out), "--target", "0.5"]) == 1
    assert "No space left on device" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()
    assert main(["simplify", "--input", str(frames), "--output", str(out), "--target", "0.5"]) == 0
    assert len(os.listdir(out)) == 3


def test_full_disk_in_the_demo_keeps_the_previous_run(capsys, tmp_path, known_registration, monkeypatch):
    out = tmp_path / "demo"
    assert main(["demo", *SMALL_DEMO, "--out-dir", str(out), "--save-meshes"]) == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert len(before) > 8
    with monkeypatch.context() as m:
        DiskFull(m, 6)
        assert main(["demo", *SMALL_DEMO, "--out-dir", str(out), "--save-meshes", "--seed", "1"]) == 1
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


@pytest.mark.parametrize("umask", [0o022, 0o027])
def test_every_output_gets_the_permissions_of_a_normal_write(capsys, tmp_path, sequence, known_registration, umask):
    expected = 0o666 & ~umask
    old = os.umask(umask)
    try:
        assert _evaluate(tmp_path, sequence, "--out", str(tmp_path / "r.json")) == 0
        simp_dir = tmp_path / "s"
        assert main(["simplify", "--input", str(sequence[0]), "--output", str(simp_dir), "--target", "0.5"]) == 0
        a, b = sorted(sequence[0].iterdir())[:2]
        reg = tmp_path / "registered.obj"
        assert main(["register", "--source", str(a), "--target", str(b), "--out", str(reg)]) == 0
    finally:
        os.umask(old)
    files = [tmp_path / f"r.{s}" for s in ("json", "md", "csv")] + sorted(simp_dir.iterdir()) + [reg]
    assert len(files) == 7
    for f in files:
        assert stat.S_IMODE(f.stat().st_mode) == expected, f


@pytest.mark.parametrize("command", ["evaluate", "simplify", "register", "demo"])
def test_an_output_below_a_regular_file_says_it_is_a_file(capsys, tmp_path, sequence, known_registration, command):
    blocker = tmp_path / "notes.txt"
    blocker.write_text("my notes")
    below = blocker / "sub"
    orig = str(sequence[0])
    a, b = sorted(sequence[0].iterdir())[:2]
    argv = {
        "evaluate": ["evaluate", "--original", orig, "--simplified", str(sequence[1]), "--out", str(below / "r.json")],
        "simplify": ["simplify", "--input", orig, "--output", str(below)],
        "register": ["register", "--source", str(a), "--target", str(b), "--out", str(below / "r.ply")],
        "demo": ["demo", *SMALL_DEMO, "--out-dir", str(below)],
    }[command]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert f"'{blocker}' is a file, not a folder" in err, err
    assert "does not exist" not in err
    assert blocker.read_text() == "my notes"
    assert known_registration.calls == 0  # refused before any computation


def test_a_missing_folder_still_says_it_does_not_exist(capsys, tmp_path, sequence, known_registration):
    assert _evaluate(tmp_path, sequence, "--out", str(tmp_path / "nope" / "r.json")) == 1
    assert "does not exist" in capsys.readouterr().err


def _register(sequence, out, *extra):
    a, b = sorted(sequence[0].iterdir())[:2]
    return main(["register", "--source", str(a), "--target", str(b), "--out", str(out), *extra])


# Found by review: an output that is a symbolic link was replaced by a regular file; a dangling one was even written
# without --overwrite (exists() follows the link), and with --overwrite the file the link points to kept its content.
def test_an_output_link_counts_as_existing_and_overwrite_writes_the_file_it_points_to(
    capsys, tmp_path, sequence, known_registration
):
    (tmp_path / "lk").mkdir()
    dangling = tmp_path / "lk" / "dangling.ply"
    dangling.symlink_to(tmp_path / "runs" / "r.ply")
    assert _register(sequence, dangling) == 1
    assert f"--out '{dangling}' already exists (pass --overwrite to replace it)" in capsys.readouterr().err
    assert _register(sequence, dangling, "--overwrite") == 1
    err = capsys.readouterr().err
    assert f"--out '{dangling}' is a symbolic link to '{tmp_path / 'runs' / 'r.ply'}', whose folder does not" in err
    assert known_registration.calls == 0 and dangling.is_symlink()  # refused before any work, the link kept
    (tmp_path / "runs").mkdir()
    assert _register(sequence, dangling, "--overwrite") == 0
    assert dangling.is_symlink() and (tmp_path / "runs" / "r.ply").stat().st_size > 0
    target = tmp_path / "runs" / "previous.ply"
    target.write_text("previous")
    link = tmp_path / "link.ply"
    link.symlink_to(target)
    assert _register(sequence, link, "--overwrite") == 0
    assert link.is_symlink() and os.readlink(link) == str(target) and target.read_bytes().startswith(b"ply")
    assert sorted(os.listdir(tmp_path / "runs")) == ["previous.ply", "r.ply"]


# Found by review: a long but legal output name failed after the computation: its temporary name (the output name
# plus ~14 characters) was over the 255-byte limit ("[Errno 36] File name too long").
def test_the_longest_legal_output_name_is_written_and_replaced(capsys, tmp_path, sequence, known_registration):
    out = tmp_path / ("a" * 246 + ".ply")
    assert _register(sequence, out) == 0, capsys.readouterr().err
    assert _register(sequence, out, "--overwrite") == 0, capsys.readouterr().err
    assert _evaluate(tmp_path, sequence, "--out", str(tmp_path / ("r" * 250 + ".json"))) == 0
    assert sorted(p for p in os.listdir(tmp_path) if p.startswith(".")) == []
    assert out.stat().st_size > 0 and (tmp_path / ("r" * 250 + ".md")).exists()


# Found by review: a mesh output in a format save_mesh cannot write (register --out r.txt or r.gltf; simplify of
# .gltf frames, whose file names the outputs keep) was refused only after the registration and the simplification.
@pytest.mark.parametrize("name", ["r.txt", "r.gltf", "r.GLTF", "r"])
def test_register_refuses_an_unwritable_mesh_format_before_any_work(
    capsys, tmp_path, sequence, known_registration, name
):
    (tmp_path / "out").mkdir()
    assert _register(sequence, tmp_path / "out" / name) == 1
    err = capsys.readouterr().err
    why = "no mesh suffix" if name == "r" else f"cannot write a mesh as '{name[1:]}'"
    assert f"--out '{tmp_path / 'out' / name}': {why}; writable formats: .obj, .ply, .off, .stl, .glb" in err
    assert known_registration.calls == 0 and os.listdir(tmp_path / "out") == []


def test_simplify_refuses_frames_it_cannot_write_before_any_work(capsys, tmp_path, known_registration):
    import trimesh

    frames = tmp_path / "gl"
    frames.mkdir()
    for k in range(3):
        trimesh.creation.icosphere(subdivisions=1).apply_translation([0.1 * k, 0, 0]).export(frames / f"f{k}.gltf")
    out = tmp_path / "glout"
    assert main(["simplify", "--input", str(frames), "--output", str(out), "--method", "rqem"]) == 1
    err = capsys.readouterr().err
    assert f"--output '{out}': the frame 'f0.gltf': cannot write a mesh as '.gltf' (the simplified frames keep" in err
    assert "the file names of --input); writable formats: .obj, .ply, .off, .stl, .glb" in err
    assert known_registration.calls == 0 and not out.exists()


def test_the_writable_suffixes_are_those_save_mesh_writes(tmp_path):
    import torch

    from torchmeshmetric import Mesh
    from torchmeshmetric.data.io import WRITABLE_MESH_SUFFIXES, save_mesh
    from torchmeshmetric.data.mesh_file import MESH_SUFFIXES, MeshFileError

    tri = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
    for suffix in MESH_SUFFIXES:
        if suffix in WRITABLE_MESH_SUFFIXES:
            assert save_mesh(tri, tmp_path / f"m{suffix}").stat().st_size > 0
        else:
            with pytest.raises(MeshFileError, match="unsupported suffix"):
                save_mesh(tri, tmp_path / f"m{suffix}")
