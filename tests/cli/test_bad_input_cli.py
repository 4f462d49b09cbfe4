"""The command line on bad frames and with --dtype: a broken frame stops the run naming the file; float64 end to end."""

import argparse
import json

import pytest
import torch

from tests.cli.cli_helpers import Counting
from torchmeshmetric.cli import main
from torchmeshmetric.data import load_sequence
from torchmeshmetric.evaluation import SET_NAMES, evaluate_sequence


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("frame_01.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "is truncated: its header"),
        ("frame_01.obj", "v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "line 1: vertex 0 has 2 coordinate"),
        ("frame_01.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "line 4: face index 0 is invalid"),
        ("frame_01.ply", b"\x00\x01garbage" * 40, "is not a mesh file"),
    ],
)
def test_a_broken_frame_stops_the_run_naming_the_file(
    capsys, tmp_path, sequence, known_registration, name, content, message
):
    orig, simp = sequence
    broken = simp / name
    (simp / "frame_01.ply").unlink()
    broken.write_bytes(content.encode() if isinstance(content, str) else content)
    out = tmp_path / "r.json"
    assert main(["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert str(broken) in err and message in err, err
    assert len(err.strip().splitlines()) == 1  # one line, no traceback
    assert not out.exists() and known_registration.calls == 0


def test_dtype_float64_runs_end_to_end_and_is_recorded(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    out = tmp_path / "r.json"
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out), "--dtype", "float64"]
    assert main(argv) == 0
    report = json.loads(out.read_text())
    assert report["settings"]["dtype"] == "float64"
    expect = evaluate_sequence(
        load_sequence(str(orig), dtype=torch.float64),
        load_sequence(str(simp), dtype=torch.float64),
        registration_fn=Counting(),
    )
    for pair, jpair in zip(expect.pairs, report["methods"]["simp"]["pairs"], strict=True):
        for s in SET_NAMES:
            assert jpair[s]["ave"] == float(pair.statistics[s].ave)


def test_dtype_default_is_float32(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    out = tmp_path / "r.json"
    assert main(["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out)]) == 0
    assert json.loads(out.read_text())["settings"]["dtype"] == "float32"


def test_dtype_rejects_half(capsys):
    with pytest.raises(SystemExit) as info:
        main(["evaluate", "--original", "a", "--simplified", "b", "--dtype", "float16"])
    assert info.value.code == 2
    assert "invalid choice: 'float16'" in capsys.readouterr().err


#: The metavars of the arguments that name a file, folder or file pattern (every command's).
PATH_METAVARS = {
    "DIR", "FILE", "FILE.ply", "REPORT", "REPORT.json", "PAGE.html", "MANIFEST", "REF", "DIS", "IMG", "MESH", "OUT",
    "PATTERN", "OBJ", "PNG", "ANCHOR.csv", "TEST.csv", "ORIGINAL", "DISTORTED",
}  # fmt: skip


def _path_arguments() -> list[tuple[str, argparse.Action]]:
    from torchmeshmetric.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return [(name, a) for name, p in sub.choices.items() for a in p._actions if a.metavar in PATH_METAVARS]


def test_every_path_argument_refuses_an_empty_path():
    from torchmeshmetric.cli.options import cache_folder, path_argument

    arguments = _path_arguments()
    # every command that reads or writes files has some (bdrate's CSVs, mpeg's meshes, ...): the list is complete
    assert len(arguments) >= 50 and {n for n, _ in arguments} >= {"evaluate", "ctc", "bdrate", "temporal", "report"}
    for name, action in arguments:
        assert action.type in (path_argument, cache_folder), (name, action.dest)
    with pytest.raises(argparse.ArgumentTypeError, match="expected a path, found ''"):
        path_argument("")
    with pytest.raises(argparse.ArgumentTypeError, match="expected a path, found ' '"):
        cache_folder(" ")


@pytest.mark.parametrize("option", ["--original", "--simplified", "--cache-dir", "--out"])
def test_an_empty_path_is_a_usage_error_not_the_current_folder(capsys, tmp_path, sequence, known_registration, option):
    # Path("") is ".": an unset shell variable would read the current folder's meshes or write the cache there.
    orig, simp = sequence
    given = {"--original": str(orig), "--simplified": str(simp), "--cache-dir": str(tmp_path / "c"), "--out": "r.json"}
    argv = ["evaluate"] + [x for k, v in {**given, option: ""}.items() for x in (k, v)]
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2 and known_registration.calls == 0
    assert f"argument {option}: expected a path, found ''" in capsys.readouterr().err


def test_a_cache_folder_that_is_a_file_is_refused_before_any_registration(
    capsys, tmp_path, sequence, known_registration
):
    orig, simp = sequence
    cache = tmp_path / "cache"
    cache.write_text("not a folder")
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--original", str(orig), "--simplified", str(simp), "--cache-dir", str(cache)])
    assert exit_info.value.code == 2 and known_registration.calls == 0
    err = capsys.readouterr().err
    assert f"argument --cache-dir: expected a folder (created when needed), found the file {str(cache)!r}" in err
    assert cache.read_text() == "not a folder"


def test_target_is_read_as_the_library_reads_it():
    from torchmeshmetric.cli.options import parse_target

    # "1.0" was a count of one face; as in the library, a number with a point is a ratio in (0, 1]
    assert parse_target("1.0") == 1.0 and isinstance(parse_target("1.0"), float)
    assert parse_target("1") == 1 and isinstance(parse_target("1"), int)
    assert parse_target("2e-1") == 0.2 and parse_target("1200") == 1200
    for bad in ("0", "-3", "0.0", "1.5", "2.0", "nan", "x"):
        with pytest.raises(argparse.ArgumentTypeError, match="expected a face count"):
            parse_target(bad)


def test_a_weight_for_plain_qem_is_refused(capsys, tmp_path, sequence, known_registration):
    # plain QEM has no weight: --weight was ignored without a word (found by review)
    argv = ["simplify", "--input", str(sequence[0]), "--output", str(tmp_path / "out"), "--method", "qem"]
    assert main([*argv, "--weight", "0.5"]) == 1
    assert "--weight: applies to --method rqem and tracking, not qem" in capsys.readouterr().err
    assert not (tmp_path / "out").exists() and known_registration.calls == 0
    assert main(argv) == 0
