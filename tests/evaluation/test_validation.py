"""The validation study: rank correlation, and the issue's goals on the flicker set at the reduced size."""

import json
import os

import pytest

from torchmeshmetric.cli import main
from torchmeshmetric.evaluation.validation import DISTORTIONS, run_validation, spearman

NAMES = "noise, simplification, constant_offset, alternating_offset, sliding, resimplification, registration"


def test_spearman_known_answers_and_ties():
    assert spearman([1, 2, 3, 4], [10.0, 20.0, 25.0, 100.0]) == 1.0
    assert spearman([1, 2, 3, 4], [4.0, 3.0, 2.0, 1.0]) == -1.0
    # ties share their mean rank: ranks of y are (0.5, 0.5, 2, 3) -> rho = 0.9486832980505138
    assert spearman([1, 2, 3, 4], [1.0, 1.0, 2.0, 3.0]) == pytest.approx(0.9486832980505138, rel=1e-12)
    assert spearman([1, 2, 3], [5.0, 5.0, 5.0]) != spearman([1, 2, 3], [5.0, 5.0, 5.0])  # NaN: nothing to rank
    stats = pytest.importorskip("scipy.stats")
    x, y = [0, 1, 2, 3, 4, 5], [0.3, 0.1, 0.9, 0.9, 2.0, 1.5]
    assert spearman(x, y) == pytest.approx(float(stats.spearmanr(x, y).statistic), rel=1e-12)


def test_flicker_rises_with_alternating_offsets_and_ignores_a_constant_offset():
    """Goals: on the built-in sequence the flicker Ave is monotone in the injected flicker strength (Spearman >= 0.95
    over 6 strengths) and changes by < 10 % under a constant offset of the same sizes."""
    r = run_validation(distortions=["alternating_offset", "constant_offset"], two_sided=False)
    alternating = r.distortions["alternating_offset"]
    constant = r.distortions["constant_offset"]
    assert len(alternating["strengths"]) >= 5 and alternating["strengths"] == constant["strengths"]
    assert alternating["spearman"]["flicker"]["ave"] >= 0.95
    flicker = alternating["values"]["flicker"]["ave"]
    assert flicker[-1] > 3 * flicker[0]  # ~2 s of flicker at s = 0.2 % of the diagonal, over a ~0.1 % floor
    steady = constant["values"]["flicker"]["ave"]
    assert max(abs(v / steady[0] - 1) for v in steady) < 0.10
    # the constant offset is a frame-k error: surface_k sees it, exactly its size
    assert constant["values"]["surface_k"]["ave"][-1] == pytest.approx(constant["strengths"][-1], rel=0.02)
    with pytest.raises(ValueError, match="unknown"):
        run_validation(distortions=["wobble"])


def test_an_empty_list_of_distortions_is_refused_before_any_work():
    from torchmeshmetric.evaluation.validation import check_validation_arguments

    # review G, finding 9: it ran nothing, then failed on its empty tables with a bare KeyError 'ave'
    with pytest.raises(ValueError) as info:
        check_validation_arguments(frames=3, resolution=16, keep=0.5, distortions=[])
    assert str(info.value) == f"distortions: expected at least one name from {list(DISTORTIONS)}, found none"
    assert ", ".join(DISTORTIONS) == NAMES


def test_validate_command_reduced_size(capsys, tmp_path):
    """The command as documented, at its reduced default size (seconds of CPU; a minute or two under load)."""
    out = tmp_path / "v"
    assert main(["validate", "--out-dir", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "Spearman rank correlation" in stdout and "| alternating_offset |" in stdout
    data = json.loads((out / "validation.json").read_text())
    assert list(data["distortions"]) == list(DISTORTIONS) and data["settings"]["two_sided"]
    registration = data["distortions"]["registration"]["values"]
    assert registration["registration:error"]["ave"][0] == 0.0  # the true registration has no error to the truth
    assert spearman(data["distortions"]["registration"]["strengths"], registration["registration:error"]["ave"]) == 1
    assert (out / "validation.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["validate", "--out-dir", str(out), "--distortions", "noise"]) == 1  # exists: never overwritten
    assert "--overwrite" in capsys.readouterr().err


# Found by review: validate made its --out-dir before checking its options (an invalid one left an empty folder),
# named the library's arguments (--keep 0 gave "target: ..."), ran --frames 100000 for minutes, and wrote its three
# files one by one.
@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--frames", "2"], "argument --frames: expected an integer from 3 to 24, found '2'"),
        (["--frames", "100000"], "argument --frames: expected an integer from 3 to 24, found '100000'"),
        (["--resolution", "3"], "argument --resolution: expected an integer >= 16, found '3'"),
        (["--keep", "0"], "argument --keep: expected a ratio in (0, 1], found '0'"),
        (["--keep", "1.5"], "argument --keep: expected a ratio in (0, 1], found '1.5'"),
        # review G, finding 9: "," ran no distortion and died with "error: 'ave'"; "" ran every distortion; unknown
        # names exited 1 without the usage
        (["--distortions", ","], f"argument --distortions: expected comma-separated names from {NAMES}, found ','"),
        (["--distortions", ""], f"argument --distortions: expected comma-separated names from {NAMES}, found ''"),
        (
            ["--distortions", "noise,wobble"],
            f"argument --distortions: expected comma-separated names from {NAMES}, found 'wobble'",
        ),
    ],
)
def test_validate_checks_its_options_before_the_folder_and_any_work(capsys, tmp_path, monkeypatch, argv, message):
    import torchmeshmetric.evaluation.validation as validation

    monkeypatch.setattr(validation, "demo_sequence", lambda *a, **k: pytest.fail("the work started"))
    out = tmp_path / "new" / "v"
    # usage errors since review E (exit 2 with usage, as docs/cli.md says of out-of-range values; they exited 1)
    with pytest.raises(SystemExit) as info:
        main(["validate", *argv, "--out-dir", str(out)])
    assert info.value.code == 2
    assert f"torchmeshmetric validate: error: {message}" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()


def test_the_frame_cap_is_one_motion_cycle_of_the_built_in_sequence():
    import inspect

    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.evaluation.validation import MAX_FRAMES

    assert inspect.signature(demo_sequence).parameters["frames_per_cycle"].default == MAX_FRAMES


def test_validate_writes_its_files_as_one_set(capsys, tmp_path, monkeypatch):
    from tests.test_atomic import DiskFull

    out = tmp_path / "new" / "v"
    argv = ["validate", "--frames", "3", "--resolution", "16", "--distortions", "alternating_offset"]
    with monkeypatch.context() as m:
        DiskFull(m, 3)  # the PNG, after the JSON and the Markdown
        assert main([*argv, "--out-dir", str(out)]) == 1
    err = capsys.readouterr().err
    assert "validate: 1 distortions x 6 strengths, each an evaluation of 2 frame pairs at resolution 16" in err
    assert "could not write the validation study: No space left on device; none of its files was written" in err
    assert not (tmp_path / "new").exists()
    assert main([*argv, "--out-dir", str(out)]) == 0
    assert sorted(os.listdir(out)) == ["validation.json", "validation.md", "validation.png"]
