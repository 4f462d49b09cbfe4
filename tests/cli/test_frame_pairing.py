"""Frames are paired by the numbers in their file names, never by position alone (found by review E, finding 1).

Before, a simplified folder missing frame 1's export ({0, 2, 3} against {0, 1, 2}) was measured position by position:
original frame 1 against simplified frame 2, with exit 0 and figures 700x too large.
"""

import json
import shutil

import pytest
import trimesh

from tests.cli.cli_helpers import STEP, write_frames
from torchmeshmetric.cli import main
from torchmeshmetric.data.frames import frame_numbers


def _frames(folder, numbers, subdivisions=1, name="frame_{:02d}.ply"):
    folder.mkdir()
    for k in numbers:
        m = trimesh.creation.icosphere(subdivisions=subdivisions)
        m.apply_translation([STEP * k, 0, 0])
        m.export(folder / name.format(k))
    return folder


def test_frame_numbers_reads_the_last_number_of_the_stem():
    assert frame_numbers(["seq2/take3_frame_010.ply", "b_2.obj", "7.off"]) == [10, 2, 7]
    assert frame_numbers(["a.ply", "frame_1.ply"]) is None  # a name without a number: position pairing
    assert frame_numbers(["a_1.ply", "b_1.ply"]) is None  # a number twice: position pairing


def _command(command, orig, simp, tmp_path):
    if command == "evaluate":
        return ["evaluate", "--original", str(orig), "--simplified", str(simp), "--one-sided"]
    if command == "compare":
        return ["compare", "--original", str(orig), "--method", f"Q={simp}", "--one-sided"]
    manifest = tmp_path / "c.toml"
    manifest.write_text(
        f'[options]\ntwo_sided = false\n[[sequences]]\nname = "g"\noriginal = "{orig.name}"\n'
        f'methods = {{ "Q" = "{simp.name}" }}\n'
    )
    return ["campaign", str(manifest)]


@pytest.mark.parametrize("command", ["evaluate", "compare", "campaign"])
def test_a_missing_frame_is_refused_naming_both_folders_and_the_frame(tmp_path, capsys, known_registration, command):
    orig = _frames(tmp_path / "orig", (0, 1, 2), subdivisions=2)
    simp = _frames(tmp_path / "simp", (0, 2, 3))  # frame 1's export is missing
    assert main(_command(command, orig, simp, tmp_path)) == 1
    err = capsys.readouterr().err
    assert "frame 1 ('frame_01.ply')" in err and str(orig) in err and str(simp) in err, err
    expected = {
        "evaluate": ("--simplified", "is in --original"),
        "compare": ("--method Q", "is in --original"),
        "campaign": ("sequence 'g': method 'Q'", "is in sequence 'g': original"),
    }[command]
    assert all(e in err for e in expected), err
    assert known_registration.calls == 0  # refused before any work


def test_another_numbering_is_refused_at_the_first_number_in_one_folder_only(tmp_path, capsys, known_registration):
    orig = _frames(tmp_path / "orig", (1, 2, 3), subdivisions=2)
    simp = _frames(tmp_path / "simp", (0, 1, 2))  # numbered from 0: frame 0 is in --simplified only
    assert main(_command("evaluate", orig, simp, tmp_path)) == 1
    err = capsys.readouterr().err
    assert "frame 0 ('frame_00.ply') is in --simplified" in err and "but not in --original" in err, err


def test_frames_pair_by_number_whatever_their_names_sort_as(tmp_path, capsys, known_registration):
    orig = write_frames(tmp_path / "orig", 2)
    right = write_frames(tmp_path / "right", 1)
    mixed = tmp_path / "mixed"  # natural order b_0, c_2, z_1: by position frame 1 met frame 2's simplification
    mixed.mkdir()
    for k, prefix in ((0, "b"), (1, "z"), (2, "c")):
        shutil.copy(right / f"frame_{k:02d}.ply", mixed / f"{prefix}_{k}.ply")
    reports = {}
    for simp in (right, mixed):
        out = tmp_path / f"{simp.name}.json"
        argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--name", "m", "--out", str(out)]
        assert main(argv) == 0
        reports[simp.name] = json.loads(out.read_text())["methods"]["m"]["aggregate"]
    capsys.readouterr()
    assert reports["mixed"] == reports["right"]
    assert reports["right"]["surface_k"]["ave"] < 0.2 * STEP  # the coarse sphere's own error, not the motion's


def test_names_without_numbers_still_pair_by_natural_order(tmp_path, capsys, known_registration):
    orig = write_frames(tmp_path / "orig", 2)
    plain = tmp_path / "plain"
    plain.mkdir()
    right = write_frames(tmp_path / "right", 1)
    for k, name in enumerate(("a", "b", "c")):
        shutil.copy(right / f"frame_{k:02d}.ply", plain / f"{name}.ply")
    argv = ["evaluate", "--original", str(orig), "--simplified", str(plain), "--one-sided"]
    assert main(argv) == 0
