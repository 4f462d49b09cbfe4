"""Registration functions without a lasting name: the cache holds them weakly; metrics tell them apart (review J)."""

from __future__ import annotations

import functools
import gc
import weakref

import pytest
import torch

from torchmeshmetric.evaluation import TemporalConsistency
from torchmeshmetric.registration import RegistrationCache


def _shift(source, target, *, by):  # a caller's registration: source moved by `by`
    return source


class _Model:
    """Stands for what a partial may capture (a network): it must die with its last user."""


def test_the_cache_does_not_keep_a_nameless_function_alive():
    # The cache held every lambda and partial it had named, and what they captured: a model in a partial outlived its
    # last user, and 50 fresh partials left 50 names for one cached registration (found by review J).
    cache = RegistrationCache()
    model = _Model()
    alive = weakref.ref(model)
    fn = functools.partial(_shift, by=model)
    name = cache.session_name(fn)
    assert cache.session_name(fn) == name  # the same object keeps its name while it lives
    del fn, model
    gc.collect()
    assert alive() is None
    assert cache._sessions == {}
    for _ in range(50):
        cache.session_name(functools.partial(_shift, by=1.0))
    gc.collect()
    assert cache._sessions == {}


def test_an_object_without_weak_references_is_held_and_named():
    class Slotted:
        __slots__ = ()

        def __call__(self, source, target):
            return source

    cache = RegistrationCache()
    fn = Slotted()
    assert cache.session_name(fn) == cache.session_name(fn)
    assert cache.session_name(Slotted()) != cache.session_name(fn)


def test_temporal_consistency_tells_nameless_functions_apart():
    # A lambda or partial had the default registration's settings (registration_fn=None): merge_state pooled their
    # sets silently and MetricCollection could group them (found by review J).
    default = TemporalConsistency()
    f, g = functools.partial(_shift, by=1.0), functools.partial(_shift, by=2.0)
    for one, other in ((default, TemporalConsistency(registration_fn=lambda s, t: s)),
                       (TemporalConsistency(registration_fn=f), TemporalConsistency(registration_fn=g))):  # fmt: skip
        with pytest.raises(ValueError, match=r"incoming_state: TemporalConsistency\(.*cannot merge into"):
            one.merge_state(other)
        assert not torch.equal(one.settings_digest, other.settings_digest)
    same = TemporalConsistency(registration_fn=f)
    TemporalConsistency(registration_fn=f).merge_state(same)  # one function object: one setting
    assert "object functools.partial(" in same._settings()
