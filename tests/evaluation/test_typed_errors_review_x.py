"""Three library calls that gave another library's error or silently missed (found by the docstrings' review)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch

from torchmeshmetric import Mesh
from torchmeshmetric._checks import EmptyInputError, ShapeError
from torchmeshmetric.evaluation.reports import write_csv
from torchmeshmetric.mpeg.comparison.pcc import bbox_diagonal
from torchmeshmetric.registration.cache import CachedRegistration, RegistrationCache, registration_key


def test_write_csv_of_no_method_is_a_value_error_naming_methods(tmp_path):
    # it raised a bare StopIteration from _best_index (paper_tables already said this)
    with pytest.raises(ValueError, match=r"^methods: expected at least one method, found none$"):
        write_csv(tmp_path / "r.csv", {})
    assert not (tmp_path / "r.csv").exists()


def test_bbox_diagonal_of_no_point_names_its_argument():
    # numpy's "zero-size array to reduction operation maximum which has no identity"
    with pytest.raises(EmptyInputError, match=r"^points: expected at least one point"):
        bbox_diagonal(np.zeros((0, 3), np.float32))
    with pytest.raises(ShapeError, match=r"^points: expected shape \(N, 3\), found \(4,\)"):
        bbox_diagonal(np.zeros(4, np.float32))
    assert bbox_diagonal(np.array([[0, 0, 0], [3, 4, 0]], np.float32)) == 5.0


class _Loss:  # no __str__: its str holds its memory address
    pass


def _files(folder):
    return [p for p in folder.rglob("*") if p.is_file()] if folder.exists() else []


def _entry(mesh):
    return CachedRegistration(mesh.verts.clone(), torch.zeros(mesh.num_verts, dtype=mesh.verts.dtype), True, 0.0)


def test_settings_keyed_by_a_memory_address_stay_in_memory_with_a_warning(tmp_path):
    # registration_key keyed such a setting by `<_Loss object at 0x7f...>`: the on-disk cache wrote entries that no
    # later process could find (every run recomputed, the folder filled up) without a word
    m = Mesh(torch.eye(3, dtype=torch.float64), torch.tensor([[0, 1, 2]]))
    settings = {"register": "mine", "options": {"loss": _Loss()}}
    assert " at 0x" in str(settings["options"]["loss"])
    cache = RegistrationCache(tmp_path / "c")
    with pytest.warns(UserWarning, match=r"keyed by its str, which holds a memory address .* kept in memory only"):
        _, hit = cache.get_or_compute(m, m, settings, lambda: _entry(m))
    assert not hit and not _files(tmp_path / "c")  # nothing stored that no later process could read
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # warned once per setting
        _, hit = cache.get_or_compute(m, m, settings, lambda: _entry(m))
    assert hit  # found again in this process
    lasting = {"register": "mine", "options": {"loss": "l2"}}
    cache.get_or_compute(m, m, lasting, lambda: _entry(m))
    assert _files(tmp_path / "c")  # a JSON setting is stored on disk as before
    assert registration_key(m, m, lasting) == registration_key(m, m, {"options": {"loss": "l2"}, "register": "mine"})
