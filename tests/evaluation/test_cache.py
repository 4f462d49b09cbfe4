import functools
import os
import warnings

import pytest
import torch

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric import Mesh
from torchmeshmetric.evaluation import default_register, evaluate_sequence, register_pairs, registration_settings
from torchmeshmetric.metrics import TemporalLossCache
from torchmeshmetric.registration import (
    DEFAULT_SCHEDULE,
    CachedRegistration,
    NonRigidOptions,
    RegistrationCache,
    RegistrationWarning,
    RegistrationWarp,
    registration_key,
)
from torchmeshmetric.registration.cache import DEFAULT_REGISTER, compute_registration


def test_cache_hit_avoids_reregistration_across_methods(moving_spheres):
    original, simplified = moving_spheres
    register = TranslationRegister()
    cache = RegistrationCache()
    a = evaluate_sequence(original, simplified, registration_fn=register, registration_cache=cache)
    b = evaluate_sequence(original, original, registration_fn=register, registration_cache=cache)  # a second "method"
    assert register.calls == 3
    assert cache.misses == 3 and cache.hits == 3
    assert [p.registration_cached for p in a.pairs] == [False] * 3
    assert [p.registration_cached for p in b.pairs] == [True] * 3
    assert all(p.timings["registration"] == 0.0 for p in b.pairs)


def test_disk_cache_survives_a_new_run_and_is_keyed_by_content_and_settings(moving_spheres, tmp_path):
    original, simplified = moving_spheres
    first = TranslationRegister()
    r1 = evaluate_sequence(original, simplified, registration_fn=first, registration_cache_dir=str(tmp_path))
    assert first.calls == 3 and len(list(tmp_path.glob("*.pt"))) == 3
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]
    second = TranslationRegister()
    r2 = evaluate_sequence(original, simplified, registration_fn=second, registration_cache_dir=str(tmp_path))
    assert second.calls == 0
    for p1, p2 in zip(r1.pairs, r2.pairs, strict=True):
        assert p1.statistics == p2.statistics
    # other settings -> other key -> registered again
    third = TranslationRegister()
    evaluate_sequence(
        original, simplified, registration_fn=third, registration_cache_dir=str(tmp_path), registration_options={"x": 1}
    )
    assert third.calls == 3
    # other content -> other key
    moved = [sphere(2, offset=(0.1 * k, 0.01, 0)) for k in range(4)]
    fourth = TranslationRegister()
    evaluate_sequence(moved, simplified, registration_fn=fourth, registration_cache_dir=str(tmp_path))
    assert fourth.calls == 3


def test_corrupt_disk_entry_is_recomputed(tmp_path):
    a, b = sphere(1), sphere(1, offset=(0.1, 0, 0))
    register = TranslationRegister()
    evaluate_sequence([a, b], [a, b], registration_fn=register, registration_cache_dir=str(tmp_path))
    (entry,) = tmp_path.glob("*.pt")
    entry.write_bytes(b"not a torch file")
    again = TranslationRegister()
    with pytest.warns(UserWarning, match="is unreadable"):
        evaluate_sequence([a, b], [a, b], registration_fn=again, registration_cache_dir=str(tmp_path))
    assert again.calls == 1


def test_key_depends_on_the_content_and_the_registration_dtype():
    a = sphere(1)
    a32 = a.to(dtype=torch.float32)
    assert registration_key(a, a, {}) != registration_key(a, sphere(1, radius=2.0), {})
    # Review I #4: float32 and float64 registrations of the same vertex values differ by 5-45 % of the registration's
    # error, so they are two entries. The key counts the dtype the registration computes in (promoted, at least
    # float32): a float64 source registers in float64 whatever the target's storage.
    a64 = a32.to(dtype=torch.float64)
    assert registration_key(a32, a32, {}) != registration_key(a64, a64, {})
    assert registration_key(a64, a32, {}) == registration_key(a64, a64, {}) == registration_key(a32, a64, {})


def test_a_float64_run_is_not_served_float32_registrations(tmp_path):
    # Review I #4: `campaign --dtype float64` after a float32 run reused its registrations (24 table rows differed from
    # a fresh float64 run). The default registration, a few steps on a small pair.
    source, target = sphere(1), sphere(1, radius=1.1)
    source32, target32 = source.to(dtype=torch.float32), target.to(dtype=torch.float32)
    options = {"schedule": DEFAULT_SCHEDULE[:1], "num_points": 50, "num_target_samples": 50}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RegistrationWarning)  # one short stage: not converged, said so
        cache = RegistrationCache(tmp_path)
        (reg32,) = register_pairs([source32, target32], registration_options=options, registration_cache=cache)
        (reg64,) = register_pairs(
            [source32.to(dtype=torch.float64), target32.to(dtype=torch.float64)],
            registration_options=options,
            registration_cache=RegistrationCache(tmp_path),
        )
        (fresh64,) = register_pairs(
            [source32.to(dtype=torch.float64), target32.to(dtype=torch.float64)], registration_options=options
        )
    assert (cache.hits, cache.misses) == (0, 1) and len(list(tmp_path.glob("*.pt"))) == 2
    assert reg32.verts.dtype == torch.float32 and reg64.verts.dtype == torch.float64
    assert torch.equal(reg64.verts, fresh64.verts)  # the float64 registration, not the float32 one
    assert not torch.equal(reg64.verts, reg32.verts.double())
    # Review L #2: the evaluation registers float32 frames in float64 too, and rounds the result to float32 once.
    assert torch.equal(reg32.verts, reg64.verts.float()) and torch.equal(reg32.residual, reg64.residual.float())


def test_the_loss_and_the_evaluation_keep_float32_frames_registrations_apart(tmp_path):
    # Review L #2: the evaluation registers float32 frames in float64 (the same figures on every CPU), the temporal
    # loss in float32 (a float32 training loop's speed); one cache must not serve one's entry to the other. Float64
    # frames are one computation for both, one entry (test_loss_and_evaluation_share_registrations).
    source, target = sphere(1).to(dtype=torch.float32), sphere(1, radius=1.1).to(dtype=torch.float32)
    options = NonRigidOptions(schedule=DEFAULT_SCHEDULE[:1], num_points=50, num_target_samples=50)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RegistrationWarning)  # one short stage: not converged, said so
        cache = RegistrationCache(tmp_path)
        (evaluation,) = register_pairs([source, target], registration_options=options, registration_cache=cache)
        TemporalLossCache(registrations=cache).warp(target, source, options, "auto")
        own32 = compute_registration(source, target, options=options)
    assert (cache.hits, cache.misses, len(cache)) == (0, 2, 2) and len(list(tmp_path.glob("*.pt"))) == 2
    assert evaluation.verts.dtype == own32.verts.dtype == torch.float32
    assert not torch.equal(evaluation.verts, own32.verts)
    assert registration_settings(None, {})["computes_in"] == "float64"


def test_key_of_plain_settings_is_stable():
    # Entries on disk are found by these digests: keying NonRigidOptions must not move the keys of plain settings.
    m = Mesh(torch.eye(3, dtype=torch.float64), torch.tensor([[0, 1, 2]]))
    # Changed on purpose (review I #4): the key holds the registration's dtype, so float32 entries are not float64's.
    assert registration_key(m, m, {}) == "27a63c7f64f6d3f818e85bf533ca75b82f57953d811d292c433ed50fcf2d3f35"
    plain = {"register": "torchmeshmetric.evaluation.pipeline.default_register",
             "options": {"schedule": DEFAULT_SCHEDULE[:1], "num_points": 10}}  # fmt: skip
    # Changed on 2026-12-02 on purpose: a Stage has a lr_decay field (the converged schedule), so registrations cached
    # by the earlier, unconverged schedule are recomputed instead of being reused; and for the dtype (review I #4).
    assert registration_key(m, m, plain) == "dc035c06facab2d264bf16e95bb30698ae956eca1312b2ee82261dc8a63c3873"


def test_default_registration_is_keyed_by_its_complete_options():
    # The library's registration is keyed by NonRigidOptions (defaults filled): equal settings spelled differently
    # share an entry, run arguments (threads, backend) do not enter, different settings never share.
    m = Mesh(torch.eye(3, dtype=torch.float64), torch.tensor([[0, 1, 2]]))
    key = lambda options: registration_key(m, m, registration_settings(None, options))  # noqa: E731
    assert key({}) == key({"schedule": DEFAULT_SCHEDULE}) == key({"num_threads": 2, "backend": "bvh"})
    assert key({"num_points": 10}) != key({})
    assert key({"schedule": DEFAULT_SCHEDULE[:1]}) != key({})
    with pytest.raises(TypeError):
        registration_settings(None, {"num_pointz": 10})


def test_default_register_name_is_the_one_of_the_disk_entries():
    # The library's registration is keyed by this name (evaluation and temporal loss alike); existing caches hold it.
    assert f"{default_register.__module__}.{default_register.__qualname__}" == DEFAULT_REGISTER
    assert registration_settings(None, {})["register"] == DEFAULT_REGISTER


def test_memory_bound_drops_the_least_recently_used(tmp_path):
    frames = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(4)]
    a, b, c = (frames[0], frames[1]), (frames[1], frames[2]), (frames[2], frames[3])
    calls = []

    def get(cache: RegistrationCache, pair: tuple[Mesh, Mesh]) -> bool:
        def compute() -> CachedRegistration:
            calls.append(pair)
            return CachedRegistration(pair[1].verts, torch.zeros(pair[0].num_verts), True, 0.0)

        return cache.get_or_compute(pair[0], pair[1], {}, compute)[1]

    cache = RegistrationCache(max_entries=2)
    assert [get(cache, p) for p in (a, b, a, c)] == [False, False, True, False]  # c drops b, not a (used last)
    assert len(cache) == 2
    assert [get(cache, p) for p in (a, c, b)] == [True, True, False]  # b was dropped: registered again
    assert len(calls) == 4 and (cache.hits, cache.misses) == (3, 4) and len(cache) == 2
    unbounded = RegistrationCache()
    assert [get(unbounded, p) for p in (a, b, c, a, b, c)] == [False] * 3 + [True] * 3 and len(unbounded) == 3
    # The bound is on memory only: a dropped entry is found again on disk, not recomputed.
    disk = RegistrationCache(tmp_path, max_entries=1)
    calls.clear()
    assert [get(disk, p) for p in (a, b, a)] == [False, False, True]
    assert len(calls) == 2 and len(disk) == 1 and len(list(tmp_path.glob("*.pt"))) == 2
    for bad, error in ((0, ValueError), (-1, ValueError), (True, TypeError), (2.0, TypeError)):  # check_int's rule
        with pytest.raises(error, match=r"^max_entries: expected an int"):
            RegistrationCache(max_entries=bad)  # type: ignore[arg-type]


def test_a_cache_directory_that_is_a_file_is_refused_at_once(tmp_path):
    # Checked when the cache is made: an entry is stored only after its registration ran.
    path = tmp_path / "cache"
    path.write_text("kept")
    with pytest.raises(ValueError, match="directory: expected a folder for the cache's entries, found the file"):
        RegistrationCache(path)
    assert path.read_text() == "kept"
    assert RegistrationCache(tmp_path / "new").directory == tmp_path / "new"  # a missing folder: made when needed


def test_the_librarys_registrations_are_keyed_by_their_results_version(tmp_path, monkeypatch):
    # Review I #5: no library or algorithm version was in the key, so entries written before a fix that changed every
    # registration (without a new option) were served after it. REGISTRATION_RESULTS_VERSION is raised with such a
    # fix; the earlier entries then miss, without a warning, and stay on disk untouched.
    from torchmeshmetric.registration import cache as cache_module

    a, b = sphere(1), sphere(1, offset=(0.1, 0, 0))
    calls = []

    def compute() -> CachedRegistration:
        calls.append(cache_module.REGISTRATION_RESULTS_VERSION)
        return CachedRegistration(b.verts * 1.0, torch.zeros(a.num_verts, dtype=a.dtype), True, 0.0)

    # 2 since review L #2 (the evaluation's registration of float32 frames computes in float64); 3 since review L #1
    # (the evaluation's registration samples with sampling="canonical").
    assert registration_settings(None, {})["results_version"] == cache_module.REGISTRATION_RESULTS_VERSION == 3
    first = RegistrationCache(tmp_path).get_or_compute(a, b, registration_settings(None, {}), compute)
    monkeypatch.setattr(cache_module, "REGISTRATION_RESULTS_VERSION", 4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a clean miss: no "unreadable" or "invalid" entry
        cache = RegistrationCache(tmp_path)
        second = cache.get_or_compute(a, b, registration_settings(None, {}), compute)
        again = RegistrationCache(tmp_path).get_or_compute(a, b, registration_settings(None, {}), compute)
    assert calls == [3, 4] and (first[1], second[1], again[1]) == (False, False, True)
    assert (cache.hits, cache.misses) == (0, 1) and len(list(tmp_path.glob("*.pt"))) == 2


def test_the_evaluations_canonical_sampling_is_keyed_apart_and_a_named_sampling_wins():
    # Review L #1: the evaluation's registration samples with sampling="canonical" (draws independent of the frames'
    # storage order) unless its options name one; its key names it, so entries of the index draws (and those of
    # results version 2) are never served for it, and {"sampling": "index"} keys (and runs) the index draws.
    from torchmeshmetric.evaluation.pipeline import REGISTRATION_SAMPLING, evaluation_keywords, registration_keywords
    from torchmeshmetric.registration import NonRigidOptions

    default = registration_settings(None, {})
    assert REGISTRATION_SAMPLING == "canonical" and default["options"].sampling == "canonical"
    index = registration_settings(None, {"sampling": "index"})
    assert index["options"].sampling == "index" and index != default
    assert "sampling" not in index["options"].canonical()  # "index" is left out of the key, as before the option
    # A NonRigidOptions is the same settings as its fields spelled as keywords; its non-default sampling wins.
    spelled = registration_keywords(NonRigidOptions(num_points=500))
    assert registration_settings(None, spelled) == registration_settings(None, {"num_points": 500})
    dense = registration_settings(None, {"options": NonRigidOptions(sampling="dense")})
    assert dense["options"].sampling == "dense"
    assert evaluation_keywords({"sampling": "index", "num_points": 5}) == {"sampling": "index", "num_points": 5}


def test_an_entry_edited_in_place_by_its_caller_changes_no_later_hit(tmp_path):
    # Review I #7: entries were handed out by reference: scaling the registered mesh in place (m.verts.mul_(1.01))
    # changed every later hit of the process (k-1 average 0.0063619 -> 0.0055274), not the disk entry.
    a, b = sphere(1), sphere(1, offset=(0.1, 0, 0))

    def fresh() -> CachedRegistration:  # each computation makes new tensors
        eye = torch.eye(3, dtype=a.dtype)
        warp = RegistrationWarp(
            torch.eye(4, dtype=a.dtype), torch.zeros(3, dtype=a.dtype), torch.tensor(2.0, dtype=a.dtype),
            a.verts[:4] / 2, eye.expand(4, 3, 3).clone(), torch.zeros(4, 3, dtype=a.dtype), 4,
        )  # fmt: skip
        return CachedRegistration(b.verts.clone(), torch.zeros(a.num_verts, dtype=a.dtype), True, 0.5, warp)

    want = b.verts.clone()
    for cache in (RegistrationCache(), RegistrationCache(tmp_path)):
        first, hit = cache.get_or_compute(a, b, {}, fresh)
        assert not hit
        first.registered_mesh(a).verts.mul_(1.01)  # the caller's post-processing of "its" registered mesh
        first.residual.add_(1.0)
        first.warp.translations.add_(5.0)
        second, hit = cache.get_or_compute(a, b, {}, lambda: pytest.fail("computed again"))
        assert hit and torch.equal(second.verts, want) and float(second.residual.abs().max()) == 0.0
        assert float(second.warp.translations.abs().max()) == 0.0
        second.verts.zero_()
        third, _ = cache.get_or_compute(a, b, {}, lambda: pytest.fail("computed again"))
        assert torch.equal(third.verts, want) and third.verts.data_ptr() != second.verts.data_ptr()
    adopted = RegistrationCache()
    adopted.adopt({"k": first})
    first.verts.zero_()
    assert torch.equal(adopted._memory["k"].verts, want * 1.01)  # kept as adopted, not as edited since


def _shift(source: Mesh, target: Mesh) -> Mesh:
    """A plain module-level registration (a lasting name): the source moved by +0.1 in x."""
    return Mesh(source.verts + torch.tensor([0.1, 0.0, 0.0], dtype=source.dtype), source.faces)


def _moved_by(step: float):
    def register(source: Mesh, target: Mesh) -> Mesh:
        return Mesh(source.verts + torch.tensor([step, 0.0, 0.0], dtype=source.dtype), source.faces)

    return register


def _k_minus_1_max(result) -> float:
    return float(result.pairs[0].statistics["surface_k_minus_1"].max)


def test_functions_the_cache_cannot_name_never_share_an_entry(moving_spheres, tmp_path):
    # Review I #2: a caller's function was keyed by its qualified name alone: every functools.partial was
    # "functools.partial", every lambda of a module "<module>.<lambda>", every closure of a factory the same name.
    # The second of two such functions got the first one's registrations (an identity's for the real registration).
    original, simplified = moving_spheres
    identity = functools.partial(lambda source, target: source)
    shifted = functools.partial(_moved_by(0.1))
    cache = RegistrationCache()
    a = evaluate_sequence(original, simplified, registration_fn=identity, registration_cache=cache)
    b = evaluate_sequence(original, simplified, registration_fn=shifted, registration_cache=cache)
    c = evaluate_sequence(original, simplified, registration_fn=_moved_by(0.3), registration_cache=cache)
    d = evaluate_sequence(original, simplified, registration_fn=_moved_by(0.1), registration_cache=cache)
    assert (cache.hits, cache.misses) == (0, 12)
    # surface_k_minus_1 of pair 1: the simplified frame 1 (its vertices on the sphere offset by 0.1) against frame 0
    # moved by the registration: not moved, 0.1 apart; moved by 0.1, on it; moved by 0.3, 0.2 apart.
    assert _k_minus_1_max(a) == pytest.approx(0.1, abs=1e-12)
    assert _k_minus_1_max(b) == _k_minus_1_max(d) < 1e-12
    assert _k_minus_1_max(c) == pytest.approx(0.2, abs=1e-12)
    # One function object still finds its own entries (in memory): a second method costs no registration.
    again = evaluate_sequence(original, original, registration_fn=shifted, registration_cache=cache)
    assert (cache.hits, cache.misses) == (3, 12) and all(p.registration_cached for p in again.pairs)


def test_a_cache_folder_keeps_only_functions_with_a_lasting_name(moving_spheres, tmp_path):
    original, simplified = moving_spheres
    with pytest.warns(UserWarning, match=r"registration_fn functools\.partial\(tests\.evaluation\.test_cache\._moved_by"
                      r"\.<locals>\.register, \.\.\.\) has no name that lasts beyond this process .* kept in memory "
                      r"only, not in"):  # fmt: skip
        evaluate_sequence(
            original, simplified, registration_fn=functools.partial(_moved_by(0.1)), registration_cache_dir=tmp_path
        )
    assert list(tmp_path.iterdir()) == []
    # A plain module-level function, and any callable given a cache_key, are stored: a new process finds them.
    evaluate_sequence(original, simplified, registration_fn=_shift, registration_cache_dir=tmp_path)
    named = functools.partial(_moved_by(0.3))
    named.cache_key = "shift x by 0.3"  # type: ignore[attr-defined]
    evaluate_sequence(original, simplified, registration_fn=named, registration_cache_dir=tmp_path)
    assert len(list(tmp_path.glob("*.pt"))) == 6
    cache = RegistrationCache(tmp_path)
    shifted = evaluate_sequence(original, simplified, registration_fn=_shift, registration_cache=cache)
    renamed = functools.partial(lambda s, t: pytest.fail("registered again"))
    renamed.cache_key = "shift x by 0.3"  # type: ignore[attr-defined]
    far = evaluate_sequence(original, simplified, registration_fn=renamed, registration_cache=cache)
    assert (cache.hits, cache.misses) == (6, 0)
    assert _k_minus_1_max(shifted) < 1e-12 and _k_minus_1_max(far) == pytest.approx(0.2, abs=1e-12)
    assert registration_settings(_shift, {})["register"] == "tests.evaluation.test_cache._shift"
    with pytest.raises(TypeError, match=r"^registration_fn\.cache_key: expected a non-empty str"):
        bad = functools.partial(_shift)
        bad.cache_key = 3  # type: ignore[attr-defined]
        evaluate_sequence(original, simplified, registration_fn=bad, registration_cache=cache)


def test_a_copied_cache_names_no_function_of_the_original(moving_spheres):
    # The names of functions without a lasting one are the objects' own: a copy (deepcopy, pickle) starts without them
    # (a lambda does not pickle; an id could name another object there), and its entries are found by content again.
    import copy
    import pickle

    original, simplified = moving_spheres
    shifted = functools.partial(_moved_by(0.1))
    cache = RegistrationCache()
    evaluate_sequence(original, simplified, registration_fn=shifted, registration_cache=cache)
    for twin in (copy.deepcopy(cache), pickle.loads(pickle.dumps(cache))):
        assert twin._sessions == {} and len(twin) == 3
        assert twin.session_name(shifted) != cache.session_name(shifted)
    assert cache.session_name(shifted) == cache.session_name(shifted)
