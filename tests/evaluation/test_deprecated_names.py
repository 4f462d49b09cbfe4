"""The old keyword names of evaluate_pair / evaluate_sequence / evaluate_sequences keep working, with a warning."""

import pytest
import torch

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric.evaluation import (
    RegistrationCache,
    evaluate_pair,
    evaluate_sequence,
    register_pairs,
)
from torchmeshmetric.evaluation.distributed import SequenceWork, evaluate_sequences


def _same_pair(a, b):
    assert a.frame == b.frame and a.registration_cached == b.registration_cached
    for name in a.distances:
        assert torch.equal(a.distances[name], b.distances[name]), name
    assert torch.equal(a.registration_residual, b.registration_residual)


def _same_sequence(a, b):
    assert len(a.pairs) == len(b.pairs)
    for p, q in zip(a.pairs, b.pairs, strict=True):
        _same_pair(p, q)


@pytest.fixture
def frames():
    original = [sphere(2, offset=(0.1 * k, 0, 0)) for k in range(3)]
    simplified = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(3)]
    return original, simplified


@pytest.mark.parametrize(
    ("old", "new", "value"),
    [
        ("register", "registration_fn", lambda: TranslationRegister()),
        ("register_options", "registration_options", lambda: {}),
        ("cache", "registration_cache", lambda: RegistrationCache()),
    ],
)
def test_evaluate_pair_old_keyword_warns_and_means_the_new_one(frames, old, new, value):
    (a, b, _), (_, simp, _) = frames
    kwargs = {"registration_fn": TranslationRegister()} if new != "registration_fn" else {}
    with pytest.warns(DeprecationWarning, match=rf"evaluate_pair\({old}=\.\.\.\) is deprecated; use {new}="):
        old_result = evaluate_pair(simp, b, a, **kwargs, **{old: value()})
    _same_pair(old_result, evaluate_pair(simp, b, a, **kwargs, **{new: value()}))


def test_evaluate_pair_old_registration_keyword(frames):
    (a, b, _), (_, simp, _) = frames
    registered = TranslationRegister()(a, b)
    with pytest.warns(DeprecationWarning, match="use precomputed_registration="):
        old_result = evaluate_pair(simp, b, a, registration=registered)
    _same_pair(old_result, evaluate_pair(simp, b, a, precomputed_registration=registered))


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("register", "registration_fn"),
        ("register_options", "registration_options"),
        ("cache", "registration_cache"),
        ("cache_dir", "registration_cache_dir"),
        ("registrations", "precomputed_registrations"),
    ],
)
def test_evaluate_sequence_old_keyword_warns_and_means_the_new_one(frames, tmp_path, old, new):
    original, simplified = frames
    folders = iter(("old", "new"))

    def value():
        return {
            "registration_fn": TranslationRegister(),
            "registration_options": {},
            "registration_cache": RegistrationCache(),
            "registration_cache_dir": str(tmp_path / next(folders)),
            "precomputed_registrations": register_pairs(original, registration_fn=TranslationRegister()),
        }[new]

    kwargs = {} if new == "registration_fn" else {"registration_fn": TranslationRegister()}
    with pytest.warns(DeprecationWarning, match=rf"evaluate_sequence\({old}=\.\.\.\) is deprecated; use {new}="):
        old_result = evaluate_sequence(original, simplified, **kwargs, **{old: value()})
    _same_sequence(old_result, evaluate_sequence(original, simplified, **kwargs, **{new: value()}))
    if new == "registration_cache_dir":
        assert len(list((tmp_path / "old").glob("*.pt"))) == 2  # the old name still reaches the disk cache


def test_evaluate_sequences_old_keywords(frames):
    original, simplified = frames
    work = [SequenceWork("s", original, {"m": simplified})]
    regs = [register_pairs(original, registration_fn=TranslationRegister())]
    with pytest.warns(DeprecationWarning) as record:
        (old_result,) = evaluate_sequences(work, cache=RegistrationCache(), registrations=regs)
    assert {str(w.message).split("(")[1].split("=")[0] for w in record} == {"cache", "registrations"}
    (new_result,) = evaluate_sequences(work, registration_cache=RegistrationCache(), precomputed_registrations=regs)
    _same_sequence(old_result["m"], new_result["m"])


def test_old_and_new_name_together_is_an_error(frames):
    original, simplified = frames
    with pytest.raises(TypeError, match=r"got both cache= \(deprecated\) and registration_cache="):
        evaluate_sequence(original, simplified, cache=RegistrationCache(), registration_cache=RegistrationCache())


def test_register_pairs_equals_the_pipeline_registrations(frames):
    """register_pairs fills the same cache entries evaluate_sequence uses: a later evaluation only hits."""
    original, simplified = frames
    cache, fn = RegistrationCache(), TranslationRegister()
    regs = register_pairs(original, registration_fn=fn, registration_cache=cache)
    assert len(regs) == 2 and fn.calls == 2
    for k, reg in enumerate(regs, start=1):
        mesh = reg.registered_mesh(original[k - 1])
        assert torch.equal(mesh.verts, original[k - 1].verts + torch.tensor([0.1, 0.0, 0.0], dtype=torch.float64))
        assert torch.equal(mesh.faces, original[k - 1].faces)
    result = evaluate_sequence(original, simplified, registration_fn=fn, registration_cache=cache)
    assert fn.calls == 2 and cache.hits == 2
    assert all(pair.registration_cached for pair in result.pairs)


def test_registered_mesh_checks_the_source(frames):
    original, _ = frames
    (reg, _) = register_pairs(original, registration_fn=TranslationRegister())
    with pytest.raises(ValueError, match=r"source: expected vertices of shape \(162, 3\)"):
        reg.registered_mesh(sphere(1))
