"""atomic_file_set: several files appear together or not at all (full disk, failed rename, caller's error)."""

import contextlib
import errno
import os
import stat

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric._atomic import atomic_file_set, atomic_write, missing_folder_error


class DiskFull:
    """Make the n-th fsync (the n-th file's write) fail with ENOSPC, like a disk that fills up."""

    def __init__(self, monkeypatch, fail_at: int):
        self.calls = 0
        self.fail_at = fail_at
        real = os.fsync

        def fsync(fd):
            self.calls += 1
            if self.calls == fail_at:
                raise OSError(errno.ENOSPC, "No space left on device")
            return real(fd)

        monkeypatch.setattr(os, "fsync", fsync)


def _listing(folder):
    return {p.relative_to(folder).as_posix(): (p.read_bytes() if p.is_file() else None) for p in folder.rglob("*")}


@settings(max_examples=25, deadline=None)
@given(
    n_files=st.integers(1, 5),
    n_existing=st.integers(0, 5),
    fail_at=st.integers(1, 6),
    phase=st.sampled_from(["write", "replace"]),
)
def test_a_failure_anywhere_leaves_the_folder_as_it_was(tmp_path_factory, n_files, n_existing, fail_at, phase):
    folder = tmp_path_factory.mktemp("set")
    for i in range(min(n_existing, n_files)):
        (folder / f"f{i}.txt").write_text(f"old {i}")
    before = _listing(folder)
    calls = {"n": 0}
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd):
        calls["n"] += phase == "write"
        if phase == "write" and calls["n"] == fail_at:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_fsync(fd)

    def replace(src, dst):
        calls["n"] += phase == "replace"
        if phase == "replace" and calls["n"] == fail_at:
            raise OSError(errno.EIO, "Input/output error")
        return real_replace(src, dst)

    fails = fail_at <= n_files
    mp = pytest.MonkeyPatch()
    mp.setattr(os, "fsync", fsync)
    mp.setattr(os, "replace", replace)
    try:
        with atomic_file_set() as files:
            files.mkdir(folder / "sub" / "deeper")
            for i in range(n_files):
                atomic_write(folder / f"f{i}.txt", f"new {i}", overwrite=True)
        assert not fails
    except OSError:
        assert fails
    finally:
        mp.undo()
    after = _listing(folder)
    if fails:
        assert after == before  # old files keep their content, no new file, no temp file, no new folder
    else:
        assert {k: v for k, v in after.items() if v is not None} == {
            f"f{i}.txt": f"new {i}".encode() for i in range(n_files)
        }


def test_files_are_invisible_until_the_set_ends_and_an_error_of_the_caller_discards_them(tmp_path):
    with pytest.raises(KeyError), atomic_file_set() as files:
        atomic_write(tmp_path / "a.json", "{}")
        assert not (tmp_path / "a.json").exists()
        assert files.paths == [tmp_path / "a.json"]
        raise KeyError("the caller failed")
    assert os.listdir(tmp_path) == []


def test_nested_sets_join_the_outer_one_and_cache_style_writes_can_opt_out(tmp_path, monkeypatch):
    DiskFull(monkeypatch, fail_at=3)
    with pytest.raises(OSError, match="No space left"), atomic_file_set():
        atomic_write(tmp_path / "a", "a")
        atomic_write(tmp_path / "cache", "kept", join_file_set=False)
        with atomic_file_set():
            atomic_write(tmp_path / "b", "b")
    assert os.listdir(tmp_path) == ["cache"]


def test_writing_one_path_twice_keeps_the_last(tmp_path):
    with atomic_file_set():
        atomic_write(tmp_path / "a", "1")
        atomic_write(tmp_path / "a", "2", overwrite=True)
    assert os.listdir(tmp_path) == ["a"] and (tmp_path / "a").read_text() == "2"


@pytest.mark.parametrize("umask", [0o022, 0o027, 0o077, 0o002])
def test_permissions_follow_the_umask_like_a_normal_write(tmp_path, umask):
    old = os.umask(umask)
    try:
        single = atomic_write(tmp_path / "single.txt", "x")
        with atomic_file_set():
            in_set = atomic_write(tmp_path / "in_set.txt", "x")
        with open(tmp_path / "plain.txt", "w") as fh:
            fh.write("x")
    finally:
        os.umask(old)
    expected = stat.S_IMODE((tmp_path / "plain.txt").stat().st_mode)
    assert expected == 0o666 & ~umask
    assert stat.S_IMODE(single.stat().st_mode) == expected
    assert stat.S_IMODE(in_set.stat().st_mode) == expected


def test_a_file_in_the_way_of_the_folder_is_named(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    error = missing_folder_error(tmp_path / "notes.txt" / "out")
    assert isinstance(error, NotADirectoryError)
    assert "notes.txt' is a file, not a folder" in str(error)
    with pytest.raises(NotADirectoryError, match="is a file, not a folder"):
        atomic_write(tmp_path / "notes.txt" / "out" / "report.json", "{}")
    assert isinstance(missing_folder_error(tmp_path / "nope" / "out"), FileNotFoundError)


# Found by review: a symbolic link given as the destination was replaced by a regular file. A dangling link was
# written without overwrite (exists() follows the link and says False), and with overwrite a link to a file became
# a regular file while the file it pointed to kept its old content.
@pytest.mark.parametrize("in_set", [False, True])
def test_a_link_is_an_existing_file_and_overwrite_replaces_the_file_it_points_to(tmp_path, in_set):
    target = tmp_path / "data" / "out.ply"
    target.parent.mkdir()
    target.write_text("old")
    os.chmod(target, 0o640)
    link = tmp_path / "link.ply"
    link.symlink_to(target)
    dangling = tmp_path / "dangling.ply"
    dangling.symlink_to(tmp_path / "data" / "new.ply")
    for path in (link, dangling):
        with pytest.raises(FileExistsError, match="already exists"):
            atomic_write(path, "x")
    assert not (tmp_path / "data" / "new.ply").exists()
    with atomic_file_set() if in_set else contextlib.nullcontext():
        assert atomic_write(link, "new", overwrite=True) == link
        assert atomic_write(dangling, "created", overwrite=True) == dangling
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text() == "new" and stat.S_IMODE(target.stat().st_mode) == 0o640
    assert dangling.is_symlink() and (tmp_path / "data" / "new.ply").read_text() == "created"
    assert sorted(os.listdir(tmp_path / "data")) == ["new.ply", "out.ply"]  # no temporary file left
    assert sorted(os.listdir(tmp_path)) == ["dangling.ply", "data", "link.ply"]


def test_a_dangling_link_into_a_missing_folder_is_named_and_nothing_is_written(tmp_path):
    link = tmp_path / "lk.ply"
    link.symlink_to(tmp_path / "nowhere" / "x.ply")
    with pytest.raises(FileNotFoundError, match=r"lk.ply' is a symbolic link to '.*nowhere/x.ply', whose folder"):
        atomic_write(link, "x", overwrite=True)
    assert link.is_symlink() and os.listdir(tmp_path) == ["lk.ply"]


# Found by review: the temporary name was the output name plus ~14 characters (and the backup name when replacing
# plus ~18), so an output name of 242..255 bytes, legal, failed after the computation with "File name too long".
@pytest.mark.parametrize("name", ["a" * 246 + ".ply", "é" * 125 + ".ply", "b" * 255])
def test_the_longest_legal_names_are_written_and_replaced_in_a_set(tmp_path, name):
    assert len(os.fsencode(name)) <= 255
    atomic_write(tmp_path / name, "one")
    with atomic_file_set():
        atomic_write(tmp_path / name, "two", overwrite=True)  # temporary file, then a backup of "one"
        atomic_write(tmp_path / "other.txt", "x")
    assert (tmp_path / name).read_text() == "two"
    assert sorted(os.listdir(tmp_path)) == sorted([name, "other.txt"])


def test_temporary_names_are_hidden_siblings_within_the_name_limit(tmp_path):
    from torchmeshmetric._atomic import _sibling

    for name in ("r.json", "a" * 255, "é" * 127):
        sibling = _sibling(tmp_path / name, "tmp")
        assert sibling.parent == tmp_path and sibling.name.startswith(".") and sibling.name.endswith(".tmp")
        assert len(os.fsencode(sibling.name)) <= 255
        assert sibling.name[1:].startswith(name[:10])
        sibling.name.encode("utf-8")  # cut at a character boundary, not in the middle of "é"
