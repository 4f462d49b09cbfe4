"""What every command's --help prints (review O: doubled percent signs, a developer path, a default not shown)."""

from __future__ import annotations

import pytest

from torchmeshmetric.cli import COMMANDS, main


def _help(capsys, *argv):
    with pytest.raises(SystemExit) as info:
        main([*argv, "--help"])
    assert info.value.code == 0
    return " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_no_help_shows_a_doubled_percent_sign(capsys, command):
    # "97%%", "95%%", "dec_%%04d.obj": the descriptions were escaped for a %-formatting argparse does not do to them
    text = _help(capsys, *([command] if command else []))
    assert "%%" not in text, text


def test_the_percent_signs_are_shown_single(capsys):
    assert "keep 97% of the faces" in _help(capsys, "demo")
    assert "the paper removes 3% of the triangles" in _help(capsys, "demo")
    assert "its 95% paired t interval" in _help(capsys, "compare")
    assert "printf patterns such as dec_%04d.obj" in _help(capsys, "temporal")
    assert "a pattern such as src_%04d.obj" in _help(capsys, "temporal")
    assert "e.g. dec_%04d.obj" in _help(capsys, "ctc")


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_no_help_cites_a_path_of_the_developers_tree(capsys, command):
    # mpeg --help cited "../shared/reference/mpeg", a folder beside the developers' checkout
    text = _help(capsys, *([command] if command else []))
    assert "../" not in text and "shared/reference" not in text, text


@pytest.mark.parametrize("command", ["demo", "validate"])
def test_the_output_folders_default_is_shown(capsys, command):
    from torchmeshmetric.cli import build_parser

    default = build_parser().parse_args([command]).out_dir
    assert f"--out-dir DIR output folder (default {default}," in _help(capsys, command)
