"""Disk cache entries are validated on read: an entry that loads but holds wrong data is recomputed, with a warning
that names the file; entries are written with the permissions of a normal write."""

import os
import stat

import pytest
import torch

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric.evaluation import evaluate_sequence


def _nan_verts(d):
    d["verts"][3, 1] = float("nan")


def _inf_verts(d):
    d["verts"][0, 0] = float("inf")


def _short_verts(d):
    d["verts"] = d["verts"][:-1]


def _flat_verts(d):
    d["verts"] = d["verts"][:, :2]


def _int_verts(d):
    d["verts"] = d["verts"].long()


def _nan_residual(d):
    d["residual"][0] = float("nan")


def _negative_residual(d):
    d["residual"][2] = -1.0


def _long_residual(d):
    d["residual"] = torch.cat([d["residual"], d["residual"]])


def _missing_residual(d):
    del d["residual"]


@pytest.mark.parametrize(
    ("corrupt", "message"),
    [
        (_nan_verts, "verts holds 1 NaN/Inf"),
        (_inf_verts, "verts holds 1 NaN/Inf"),
        (_short_verts, "verts expected a float tensor of shape"),
        (_flat_verts, "verts expected a float tensor of shape"),
        (_int_verts, "verts expected a float tensor of shape"),
        (_nan_residual, "residual holds 1 NaN/Inf"),
        (_negative_residual, "negative distances"),
        (_long_residual, "residual expected a float tensor of shape"),
        (_missing_residual, "unreadable"),
    ],
)
def test_invalid_entry_is_recomputed_with_a_warning_naming_the_file(tmp_path, corrupt, message):
    a, b = sphere(1), sphere(1, offset=(0.1, 0, 0))
    first = evaluate_sequence(
        [a, b], [a, b], registration_fn=TranslationRegister(), registration_cache_dir=str(tmp_path)
    )
    (entry,) = tmp_path.glob("*.pt")
    data = torch.load(entry, weights_only=True)
    corrupt(data)
    torch.save(data, entry)
    again = TranslationRegister()
    with pytest.warns(UserWarning, match=message) as record:
        second = evaluate_sequence([a, b], [a, b], registration_fn=again, registration_cache_dir=str(tmp_path))
    assert str(entry) in str(record[0].message)
    assert again.calls == 1
    assert second.pairs[0].statistics == first.pairs[0].statistics
    # the entry was replaced by a valid one: a third run trusts it silently
    third = TranslationRegister()
    evaluate_sequence([a, b], [a, b], registration_fn=third, registration_cache_dir=str(tmp_path))
    assert third.calls == 0


def test_entries_get_the_permissions_of_a_normal_write(tmp_path):
    old = os.umask(0o027)
    try:
        a, b = sphere(1), sphere(1, offset=(0.1, 0, 0))
        evaluate_sequence([a, b], [a, b], registration_fn=TranslationRegister(), registration_cache_dir=str(tmp_path))
    finally:
        os.umask(old)
    (entry,) = tmp_path.glob("*.pt")
    assert stat.S_IMODE(entry.stat().st_mode) == 0o640
