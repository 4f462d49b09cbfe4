"""Without a compiler the "bvh" backend warns once and answers through the exact pure-torch path."""

from __future__ import annotations

import warnings

import pytest
import torch

from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.native import loader


def test_compile_failure_warns_once_and_falls_back(monkeypatch):
    import torch.utils.cpp_extension as cpp

    def no_compiler(*args, **kwargs):
        raise RuntimeError("no C++ compiler")

    monkeypatch.setattr(cpp, "load", no_compiler)
    monkeypatch.setattr(loader, "_import_built", lambda name: None)  # and no earlier build on disk
    monkeypatch.setattr(loader, "_STATE", {})
    monkeypatch.setattr(loader, "_WARNED", set())
    g = torch.Generator().manual_seed(0)
    verts = torch.randn(50, 3, generator=g, dtype=torch.float64)
    faces = torch.randint(0, 50, (80, 3), generator=g)
    points = torch.randn(100, 3, generator=g, dtype=torch.float64)
    with pytest.warns(RuntimeWarning, match="could not be built"):
        got = point_mesh_distance(points, verts, faces, backend="bvh")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the second call must not warn again
        again = point_mesh_distance(points, verts, faces, backend="bvh")
    ref = point_mesh_distance(points, verts, faces, backend="bruteforce")
    assert torch.equal(got.face_idx, ref.face_idx) and torch.equal(again.face_idx, ref.face_idx)
    assert torch.equal(got.dists, ref.dists)
    with pytest.raises(loader.NativeBuildError, match=r"'bvh' could not be built: RuntimeError: no C\+\+ compiler"):
        loader.load("bvh")  # the outcome is kept for the process: no second attempt, the same error


def test_finished_build_is_imported_without_running_load(monkeypatch):
    import torch.utils.cpp_extension as cpp

    if loader.try_load("bvh") is None:  # makes sure a build exists (compiles once if needed)
        pytest.skip("the extension cannot be built here")

    def must_not_run(*args, **kwargs):
        raise AssertionError("load() ran although a finished build exists")

    monkeypatch.setattr(cpp, "load", must_not_run)
    monkeypatch.setattr(loader, "_STATE", {})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        module = loader.load("bvh")
    assert module is not None and hasattr(module, "__file__")


def test_unknown_extension_is_named():
    with pytest.raises(KeyError, match="no extension named 'nope'"):
        loader.load("nope")
