"""Options checked when parsed and inputs/outputs the system refuses, found by review X's fuzzing of the CLI."""

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


@pytest.mark.parametrize("command", ["evaluate", "compare", "demo"])
@pytest.mark.parametrize("value", ["0", "-5", str((1 << 20) + 1)])
def test_mpeg_grid_size_is_checked_when_parsed(capsys, command, value):
    # Review X, F7: `--mpeg-grid-size 0` ran every registration and the whole evaluation, then failed naming the
    # library's `grid_size`.
    argv = {"evaluate": ["--original", "o", "--simplified", "s"], "compare": ["--original", "o"], "demo": []}[command]
    line = _usage_error(capsys, [command, *argv, "--mpeg", "--mpeg-grid-size", value])
    assert f"argument --mpeg-grid-size: expected an integer from 2 to 1048576, found {value!r}" in line, line


def _unprivileged(argv, cwd):
    """Run the CLI as an ordinary user would (root ignores a folder's mode): its exit code and stderr."""
    import shutil
    import subprocess
    import sys

    prefix = []
    if os.geteuid() == 0:
        if shutil.which("setpriv") is None:
            pytest.skip("root without setpriv: permissions are not enforced")
        prefix = ["setpriv", "--bounding-set=-dac_override,-dac_read_search"]
    done = subprocess.run(
        [*prefix, sys.executable, "-m", "torchmeshmetric", *argv], cwd=cwd, capture_output=True, text=True, timeout=120
    )
    return done.returncode, done.stderr


@pytest.fixture
def unsearchable(tmp_path):
    folder = tmp_path / "noexec"
    folder.mkdir()
    folder.chmod(0)
    yield folder
    folder.chmod(0o700)


@pytest.mark.parametrize("command", [["evaluate", "--original", "o", "--simplified", "s"], ["demo"]])
def test_a_cache_dir_below_an_unsearchable_folder_is_one_usage_line(tmp_path, unsearchable, command):
    # Review X, F13: Path.is_file raised PermissionError inside argparse: a whole Python traceback, exit 1.
    code, err = _unprivileged([*command, "--cache-dir", "noexec/c"], tmp_path)
    assert code == 2 and "Traceback" not in err, err
    assert (
        err.strip()
        .splitlines()[-1]
        .endswith("error: argument --cache-dir: cannot look into 'noexec' to find 'noexec/c' (Permission denied)")
    ), err


@pytest.fixture
def meshes(tmp_path):
    import trimesh

    for name in ("a.obj", "unread.obj"):
        trimesh.creation.icosphere(subdivisions=1).export(tmp_path / name)
    for folder in ("o", "s"):
        (tmp_path / folder).mkdir()
        for k in range(2):
            trimesh.creation.icosphere(subdivisions=1).export(tmp_path / folder / f"f{k}.obj")
    (tmp_path / "unread.obj").chmod(0)
    return tmp_path


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (["mpeg", "a.obj", "unread.obj"], "error: DIS: mesh file 'unread.obj' cannot be read (permission denied)"),
        (["sample", "unread.obj", "x.ply"], "error: MESH: mesh file 'unread.obj' cannot be read (permission denied)"),
        (
            ["register", "--source", "unread.obj", "--target", "a.obj", "--out", "r.ply"],
            "error: --source: mesh file 'unread.obj' cannot be read (permission denied)",
        ),
        (
            ["evaluate", "--original", "o", "--simplified", "noexec"],
            "error: --simplified 'noexec': directory 'noexec' cannot be read (permission denied)",
        ),
        (
            ["evaluate", "--original", "o", "--simplified", "s", "--out", "noexec/r.json"],
            "error: --out 'noexec/r.json': output folder 'noexec' cannot be searched (permission denied)",
        ),
        (
            ["evaluate", "--original", "o", "--simplified", "s", "--out", "noexec/sub/r.json"],
            "error: --out 'noexec/sub/r.json': output folder 'noexec/sub': a folder above it cannot be searched "
            "(permission denied)",
        ),
    ],
)
def test_unreadable_inputs_and_unsearchable_outputs_name_the_option_and_say_permission_denied(
    meshes, unsearchable, argv, line
):
    # Review X, F14: a bare "[Errno 13] Permission denied: 'unread.obj'", mostly without REF/DIS or the option
    code, err = _unprivileged(argv, meshes)
    assert code == 1 and "Errno" not in err, err
    assert err.strip().splitlines()[-1].endswith(line), err


def test_a_mesh_reader_error_names_the_option_and_the_file_once(capsys, meshes):
    # Review X, F10: `--target 'half.ply': path: could not read mesh file 'half.ply' ...` (the reader's parameter)
    half = meshes / "half.ply"
    import trimesh

    trimesh.creation.icosphere(subdivisions=1).export(half)
    half.write_bytes(half.read_bytes()[: half.stat().st_size // 2])
    argv = ["register", "--source", str(meshes / "a.obj"), "--target", str(half), "--out", str(meshes / "r.ply")]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("torchmeshmetric register: error: --target: ") and "path:" not in err, err
    assert err.count(str(half)) == 1, err


@pytest.mark.parametrize("command", [["demo", "--frames", "2", "--resolution", "16"], ["validate", "--frames", "3"]])
def test_an_out_dir_that_cannot_be_created_is_refused_before_any_work(tmp_path, command):
    # Review X, F15: `demo --out-dir ro/d` made and simplified the sequence, then said "cannot create it"
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        code, err = _unprivileged([*command, "--out-dir", "ro/d", "--no-plots"], tmp_path)
    finally:
        ro.chmod(0o755)
    assert code == 1 and err.strip().endswith(
        "error: --out-dir 'ro/d': cannot create it (folder 'ro' is not writable)"
    ), err
    assert len(err.strip().splitlines()) == 1, err  # no progress line: nothing was made


def test_version_and_polish(capsys):
    # Review X, F19: no --version (a usage error); two --method names alike but for a trailing space were accepted
    from torchmeshmetric import __version__

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out == f"torchmeshmetric {__version__}\n"
    assert main(["compare", "--original", "o", "--method", "A=qem", "--method", "A =rqem"]) == 1
    err = capsys.readouterr().err
    assert "--method 'A =rqem': method name 'A ' differs from 'A' only by spaces around it" in err, err


def test_a_topology_map_index_out_of_range_says_vertices(tmp_path):
    # "mesh A has 482 vertexs"
    from torchmeshmetric.mpeg.comparison import topology

    mapping = tmp_path / "map.txt"
    mapping.write_text("0 9\n")
    with pytest.raises(ValueError, match=r"mesh A has 3 vertices$"):
        topology.read_topology_map(mapping, 3, "vertex")
