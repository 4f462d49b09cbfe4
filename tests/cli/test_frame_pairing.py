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
from torchmeshmetric.cli._outputs import CLIError
from torchmeshmetric.cli._shared import paired_files
from torchmeshmetric.data.frames import frame_numbers, list_frames


def _frames(folder, numbers, subdivisions=1, name="frame_{:02d}.ply"):
    folder.mkdir()
    for k in numbers:
        m = trimesh.creation.icosphere(subdivisions=subdivisions)
        m.apply_translation([STEP * k, 0, 0])
        m.export(folder / name.format(k))
    return folder


def test_frame_numbers_reads_the_first_number_position_whose_values_all_differ():
    # review F, finding 2: the last number was read, so a simplifier's face count after the frame number was taken
    # for the frame number and a right pairing refused
    assert frame_numbers(["frame_0000_f1000.ply", "frame_0001_f1007.ply", "frame_0002_f1014.ply"]) == [0, 1, 2]
    assert frame_numbers(["seq2/take3_frame_010.ply", "seq2/take3_frame_002.ply"]) == [10, 2]  # folders: not read
    assert frame_numbers(["seq2_frame_003.ply", "seq2_frame_001.ply"]) == [3, 1]  # a constant number: skipped
    assert frame_numbers(["v1.2_frame1.ply", "v1.2_frame2.ply", "v1.2_frame10.ply"]) == [1, 2, 10]
    assert frame_numbers(["frame_0001_r50.ply", "frame_0002_r50.ply"]) == [1, 2]
    assert frame_numbers(["a.ply", "frame_1.ply"]) is None  # a name without a number: position pairing
    assert frame_numbers(["a_1.ply", "b_1.ply"]) is None  # a number twice: position pairing
    assert frame_numbers(["a_1_0.ply", "a_1_1.ply", "a_2_0.ply"]) is None  # no position with distinct numbers
    assert frame_numbers(["frame_0007.ply"]) is None  # one frame: nothing to tell apart


def _touched(folder, names):
    folder.mkdir()
    for n in names:
        (folder / n).touch()
    return folder


@pytest.mark.parametrize(
    ("originals", "simplified"),
    [
        ("frame_{:04d}.ply", "frame_{:04d}.ply"),
        ("mesh-{}.obj", "mesh-{}.obj"),
        ("seq2_frame_{:03d}.ply", "seq2_frame_{:03d}.ply"),
        ("v1.2_frame{}.ply", "v1.2_frame{}.ply"),
        ("src_{:04d}.obj", "dec_{:04d}.obj"),  # V-DMC / mmetric's src_%04d / dec_%04d
        ("basketball_fr{:04d}.obj", "basketball_fr{:04d}_r3_qp10_dec.obj"),  # V-DMC decoded
        ("longdress_vox10_{}.ply", "longdress_vox10_{}_qp12_dec.ply"),
        ("frame_{:04d}.ply", "frame_{:04d}_r50.ply"),  # a constant number after the frame number
        ("frame_{:04d}.ply", "seq2_frame_{:04d}.ply"),  # a constant number in one folder only
    ],
)
def test_common_naming_schemes_pair_by_frame_number(tmp_path, originals, simplified):
    frames = (8, 9, 10, 1051) if "vox10" in originals else (8, 9, 10, 11)
    orig = _touched(tmp_path / "o", [originals.format(k) for k in frames])
    simp = _touched(tmp_path / "s", [simplified.format(k) for k in reversed(frames)])
    paired = paired_files(list_frames(simp), str(simp), "--simplified", str(orig), "--original")
    assert [p.name for p in paired] == [simplified.format(k) for k in sorted(frames)]


def test_a_face_count_after_the_frame_number_pairs_by_the_frame_number(tmp_path):
    # review F, finding 2: refused before as "frame 0 is in --original but not in --simplified"
    orig = _touched(tmp_path / "o", [f"frame_{k:04d}.ply" for k in range(3)])
    counts = (1014, 1000, 1007)  # the face counts do not follow the frames' order
    simp = _touched(tmp_path / "s", [f"frame_{k:04d}_f{c}.ply" for k, c in enumerate(counts)])
    paired = paired_files(list_frames(simp), str(simp), "--simplified", str(orig), "--original")
    assert [p.name for p in paired] == ["frame_0000_f1014.ply", "frame_0001_f1000.ply", "frame_0002_f1007.ply"]


def test_a_shifted_numbering_is_refused_with_both_starts_and_both_renames(tmp_path):
    orig = _touched(tmp_path / "o", [f"frame_{k:04d}.ply" for k in range(3)])
    simp = _touched(tmp_path / "s", [f"out_{k:04d}.ply" for k in range(1, 4)])
    with pytest.raises(CLIError) as caught:
        paired_files(list_frames(simp), str(simp), "--simplified", str(orig), "--original")
    msg = str(caught.value)
    assert "frame 0 ('frame_0000.ply') is in --original" in msg and "but not in --simplified" in msg, msg
    assert "--original starts at frame 0 ('frame_0000.ply') and --simplified at frame 1 ('out_0001.ply')" in msg, msg
    renames = "rename the frames of --simplified to start at 0, or those of --original to start at 1"
    assert f"different starts; {renames}" in msg, msg


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
