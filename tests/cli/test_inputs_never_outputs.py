"""No command writes its inputs (with or without --overwrite); the outputs of one run are distinct, checked before
any work and written all or nothing (issue 41, theme 1)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.cli.cli_helpers import write_frames
from torchmeshmetric.cli import main

QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n"
QUAD_PLY = (
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n"
)


@pytest.fixture
def meshes(tmp_path: Path) -> tuple[Path, Path]:
    ref, dis = tmp_path / "ref.ply", tmp_path / "dis.obj"
    ref.write_text(QUAD_PLY)
    dis.write_text(QUAD)
    return ref, dis


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(capsys: pytest.CaptureFixture[str], argv: list[str], *words: str) -> str:
    assert main(argv) == 1
    err = capsys.readouterr().err.splitlines()[-1]  # after any extension build's progress lines
    assert "error:" in err, err
    for w in words:
        assert w in err, err
    return err


@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]])
@pytest.mark.parametrize("spelling", ["same", "dotted", "symlink", "hardlink"])
def test_sample_never_writes_its_mesh(tmp_path, meshes, capsys, overwrite, spelling):
    ref, _ = meshes
    out = {
        "same": ref,
        "dotted": tmp_path / "." / "sub" / ".." / ref.name,
        "symlink": tmp_path / "link.ply",
        "hardlink": tmp_path / "hard.ply",
    }[spelling]
    (tmp_path / "sub").mkdir()
    if spelling == "symlink":
        out.symlink_to(ref)
    if spelling == "hardlink":
        os.link(ref, out)
    before = _snapshot(tmp_path)
    _refused(capsys, ["sample", str(ref), str(out), *overwrite], "OUT", "is the input MESH", str(ref))
    assert _snapshot(tmp_path) == before


def test_sample_never_writes_the_texture_of_its_mtl(tmp_path, capsys):
    # the texture named with OUT's suffix (.ply): the output's own suffix check passes, the input check refuses
    (tmp_path / "m.mtl").write_text("newmtl a\nmap_Kd t.ply\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nusemtl a\n" + QUAD)
    (tmp_path / "t.ply").write_bytes(b"not really a texture")
    before = _snapshot(tmp_path)
    _refused(capsys, ["sample", str(tmp_path / "m.obj"), str(tmp_path / "t.ply"), "--overwrite"], "MESH's texture")
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize(
    ("outputs", "words"),
    [
        (["--output-model-ref", "{ref}"], ["--output-model-ref", "is the input REF"]),
        (["--output-model-dis", "{ref}"], ["--output-model-dis", "is the input REF"]),
        (["--mode", "ibsm", "--output-model-ref", "{dis}"], ["--output-model-ref", "is the input DIS"]),
        (["--output-csv", "{ref}"], ["--output-csv", "is the input REF"]),
        (["--output-model-ref", "{t}/x.ply", "--output-model-dis", "{t}/x.ply"], ["is also --output-model-ref"]),
        (["--output-model-ref", "{t}/y.ply", "--output-csv", "{t}/y.ply"], ["--output-csv", "is also"]),
        (["--output-model-ref", "{t}/z.ply", "--output-csv", "{t}/other.csv"], ["--output-csv", "'x;y'"]),
    ],
)
@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]])
def test_mpeg_outputs_are_never_inputs_and_are_distinct(tmp_path, meshes, capsys, outputs, words, overwrite):
    ref, dis = meshes
    (tmp_path / "other.csv").write_text("x;y\n1;2\n")
    argv = [a.format(ref=ref, dis=dis, t=tmp_path) for a in outputs]
    before = _snapshot(tmp_path)
    sampling = [] if "--mode" in argv else ["--sampling", "mesh"]  # pcc mode's option: refused in ibsm mode
    _refused(capsys, ["mpeg", str(ref), str(dis), *sampling, *argv, *overwrite], *words)
    assert _snapshot(tmp_path) == before  # refused before any work: no model, no row, the inputs unchanged


def test_mpeg_models_are_not_kept_when_the_csv_row_cannot_be_appended(tmp_path, meshes, capsys, monkeypatch):
    ref, dis = meshes

    def full_disk(*args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device", str(tmp_path / "s.csv"))

    monkeypatch.setattr("torchmeshmetric.mpeg.comparison.csv_rows.append_csv_row", full_disk)
    before = _snapshot(tmp_path)
    models = ["--output-model-ref", str(tmp_path / "a.ply"), "--output-model-dis", str(tmp_path / "b.ply")]
    argv = ["mpeg", str(ref), str(dis), "--sampling", "mesh", *models, "--output-csv", str(tmp_path / "s.csv")]
    _refused(capsys, argv, "No space left on device", "none of its files was written")
    assert _snapshot(tmp_path) == before
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]  # no staged temporary file left


def test_register_never_writes_its_source(tmp_path, meshes, capsys):
    ref, dis = meshes
    before = _snapshot(tmp_path)
    argv = ["register", "--source", str(ref), "--target", str(dis), "--out", str(dis), "--overwrite"]
    _refused(capsys, argv, "--out", "is the input --target")
    assert _snapshot(tmp_path) == before


def test_simplify_never_writes_its_input_frames(tmp_path, capsys):
    frames = write_frames(tmp_path / "orig", 1)
    before = _snapshot(tmp_path)
    argv = ["simplify", "--input", str(frames), "--output", str(frames), "--target", "0.5", "--overwrite"]
    _refused(capsys, argv, "--output", "is the input --input", "frame_00.ply")
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["evaluate", "compare"])
def test_a_report_never_replaces_a_frame(tmp_path, sequence, capsys, command):
    orig, simp = sequence
    frame = orig / "frame_01.ply"
    args = ["--simplified", str(simp)] if command == "evaluate" else ["--method", f"m={simp}"]
    before = _snapshot(tmp_path)
    argv = [command, "--original", str(orig), *args, "--out", str(frame), "--overwrite"]
    # refused by its suffix since review E (before: "is the input --original"); the frame is kept either way
    _refused(capsys, argv, "--out", "expected a REPORT.json file name, found the suffix '.ply'")
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["evaluate", "compare"])
def test_a_report_is_never_written_into_an_input_frame_folder(tmp_path, sequence, capsys, command):
    # Found by review E: --out simp/zz_report.ply wrote a JSON named .ply among the frames, and every later run on
    # that folder failed ("is not a mesh file"); a .json there is refused too (the folder is the user's frames).
    orig, simp = sequence
    args = ["--simplified", str(simp)] if command == "evaluate" else ["--method", f"m={simp}"]
    before = _snapshot(tmp_path)
    option = "--simplified" if command == "evaluate" else "--method m"
    for out in (simp / "zz_report.ply", simp / "zz_report.json"):
        argv = [command, "--original", str(orig), *args, "--out", str(out)]
        message = "expected a REPORT.json" if out.suffix == ".ply" else f"lies in the input folder {option}"
        _refused(capsys, argv, "--out", message)
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize(
    ("name", "found"), [("r.md", "the suffix '.md'"), ("r.csv", "the suffix '.csv'"), ("r", "no suffix")]
)
def test_a_report_not_named_json_is_refused_naming_the_suffix(tmp_path, sequence, capsys, name, found):
    # `--out r.md` said "--out 'r.md' is also --out 'r.md'" (the .md is derived from --out; found by review E)
    orig, simp = sequence
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(tmp_path / name)]
    _refused(capsys, argv, f"--out {str(tmp_path / name)!r}: expected a REPORT.json file name, found {found}")
    assert not (tmp_path / name).exists()
