"""Options whose values are bounded when parsed (exit 2, the option named), found by review X's fuzzing of the CLI."""

from __future__ import annotations

import os

import pytest

from torchmeshmetric.cli import main


def _usage_error(capsys, argv):
    with pytest.raises(SystemExit) as info:
        main(argv)
    err = capsys.readouterr().err
    assert info.value.code == 2 and "usage:" in err, err
    return err.strip().splitlines()[-1]


@pytest.mark.parametrize("value", ["100000", "99999999999999999999", "0", "-3", "2.5"])
@pytest.mark.parametrize(
    "argv",
    [
        ["evaluate", "--original", "o", "--simplified", "s"],
        ["register", "--source", "a.obj", "--target", "b.obj", "--out", "r.json"],
        ["demo"],
    ],
)
def test_threads_beyond_the_machine_are_refused_when_parsed(capsys, tmp_path, argv, value):
    # Review X, F6: `--threads 100000` said "--simplified 'qem': can't start new thread" (the wrong option) and then
    # segfaulted (exit 139); `--threads 99999999999999999999` said "Overflow when unpacking long long".
    high = max(64, 4 * (os.cpu_count() or 1))
    line = _usage_error(capsys, [*argv, "--threads", value])
    assert f"argument --threads: expected an integer from 1 to {high} (4 per CPU core" in line, line
    assert line.endswith(f"found {value!r}"), line


def test_threads_within_the_bound_parse():
    from torchmeshmetric.cli import build_parser

    args = build_parser().parse_args(["evaluate", "--original", "o", "--simplified", "s", "--threads", "64"])
    assert args.threads == 64
