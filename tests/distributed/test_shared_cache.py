"""The registration cache shared by ranks and runs: complete, finite, normally readable entries or none."""

import os
import stat
import warnings

import pytest
import torch

from tests.evaluation.eval_helpers import TranslationRegister
from torchmeshmetric.evaluation import evaluate_sequence
from torchmeshmetric.registration import RegistrationCache


def _entry(tmp_path):
    files = list(tmp_path.glob("*.pt"))
    assert len(files) == 3
    return sorted(files)[0]


@pytest.mark.parametrize("damage", ["nan", "inf", "truncated", "shape"])
def test_damaged_entries_are_recomputed_with_a_warning(moving_spheres, tmp_path, damage):
    original, simplified = moving_spheres
    first = evaluate_sequence(
        original, simplified, registration_fn=TranslationRegister(), registration_cache_dir=str(tmp_path)
    )
    path = _entry(tmp_path)
    if damage == "truncated":
        path.write_bytes(path.read_bytes()[:100])
    else:
        data = torch.load(path, weights_only=True)
        if damage == "shape":
            data["residual"] = data["residual"][:-1]
        else:
            data["verts"][3, 1] = float(damage)
        torch.save(data, path)
    register = TranslationRegister()
    # An edited entry no longer matches its checksum (damaged); a truncated one cannot be read (review I #3)
    message = r"registration cache: entry .* is (damaged: .* does not match its checksum|unreadable).*recomputing"
    with pytest.warns(UserWarning, match=message):
        second = evaluate_sequence(original, simplified, registration_fn=register, registration_cache_dir=str(tmp_path))
    assert register.calls == 1  # only the damaged entry
    assert [p.statistics for p in second.pairs] == [p.statistics for p in first.pairs]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the recomputed entry replaced the damaged one
        evaluate_sequence(
            original, simplified, registration_fn=TranslationRegister(), registration_cache_dir=str(tmp_path)
        )


def test_entries_have_normal_permissions_and_no_temporary_files(moving_spheres, tmp_path):
    original, simplified = moving_spheres
    mask = os.umask(0o022)
    try:
        evaluate_sequence(
            original, simplified, registration_fn=TranslationRegister(), registration_cache=RegistrationCache(tmp_path)
        )
    finally:
        os.umask(mask)
    assert all(stat.S_IMODE(p.stat().st_mode) == 0o644 for p in tmp_path.glob("*.pt"))
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]
