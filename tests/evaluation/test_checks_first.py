"""Every frame count is checked before any work starts (issue 23).

Before: ``compare`` (and ``evaluate_sequences``, under torchrun too) evaluated the first method completely — its
registrations and distances — before it noticed that the second method had fewer frames. Now the counts of every
method (and of the precomputed registrations) are checked first, in the library, so the command line gets it too; the
tests count the registrations and frame-pair evaluations done before the error: none.
"""

from __future__ import annotations

from typing import Any

import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric.evaluation import check_methods
from torchmeshmetric.evaluation.distributed import SequenceWork, evaluate_sequences
from torchmeshmetric.mpeg import mpeg_sequence

_SPHERE = trimesh.creation.icosphere(subdivisions=1)


class _Counting:
    """A registration that counts its calls (the work that must not start)."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, source: Any, target: Any, **options: Any) -> Any:
        self.calls += 1
        return source


@st.composite
def _mismatched(draw: st.DrawFn) -> tuple[int, list[int], int]:
    """(original frame count, each method's count, index of the one wrong method)."""
    n = draw(st.integers(2, 5))
    num_methods = draw(st.integers(2, 4))
    bad = draw(st.integers(0, num_methods - 1))
    wrong = draw(st.integers(0, 7).filter(lambda c: c != n))
    return n, [wrong if i == bad else n for i in range(num_methods)], bad


@settings(max_examples=25, deadline=None)
@given(case=_mismatched(), named=st.booleans())
def test_evaluate_sequences_refuses_a_wrong_count_before_any_registration(case, named):
    n, counts, bad = case
    frames = [_SPHERE] * n
    methods = {f"m{i}": [_SPHERE] * c for i, c in enumerate(counts)}
    register = _Counting()
    name = "walk" if named else ""
    where = "sequence 'walk': " if named else ""
    # A correct sequence first: its work must not start either.
    work = [SequenceWork("ok", frames, {"m": frames}), SequenceWork(name, frames, methods)]
    with pytest.raises(ValueError, match=rf"^{where}method 'm{bad}': {counts[bad]} simplified frames but {n} orig"):
        evaluate_sequences(work, registration_fn=register)
    assert register.calls == 0


def test_check_methods_messages():
    with pytest.raises(ValueError, match=r"^the sequence has 1 frame; at least 2 are needed"):
        check_methods([_SPHERE], {"a": [_SPHERE]})
    with pytest.raises(ValueError, match=r"^sequence 's': 1 frame; at least 2 are needed"):
        check_methods([_SPHERE], {"a": [_SPHERE]}, sequence="s")
    with pytest.raises(ValueError, match=r"^methods: expected at least one method"):
        check_methods([_SPHERE] * 2, {})
    check_methods([_SPHERE] * 2, {"a": [_SPHERE] * 2, "b": [_SPHERE] * 2})  # good input: nothing raised


def test_evaluate_sequences_refuses_wrong_registration_counts_first():
    frames = [_SPHERE] * 3
    register = _Counting()
    work = [SequenceWork("", frames, {"a": frames})]
    with pytest.raises(ValueError, match=r"^precomputed_registrations: expected 1 entries"):
        evaluate_sequences(work, registration_fn=register, precomputed_registrations=[None, None])
    with pytest.raises(ValueError, match=r"^precomputed_registrations: expected 2 \(one per frame pair\), found 1"):
        evaluate_sequences(work, registration_fn=register, precomputed_registrations=[[_SPHERE]])
    assert register.calls == 0


@pytest.mark.parametrize("distorted", [0, 1, 3])
def test_mpeg_sequence_refuses_a_wrong_count_before_any_frame(monkeypatch, distorted):
    calls = []
    monkeypatch.setattr("torchmeshmetric.mpeg.comparison.sequence.mpeg_metrics", lambda *a, **k: calls.append(1))
    with pytest.raises(ValueError, match=r"^distorted: expected as many frames as the reference \(2, at least 1\)"):
        mpeg_sequence([_SPHERE] * 2, [_SPHERE] * distorted, sampling="mesh")
    assert calls == []


def test_a_faceless_frame_is_named_by_its_argument():
    # Review Q: four different frames without faces gave two identical messages naming none of them
    # ("faces: mesh 0 has no faces but 162 query points"); the temporal loss named them.
    import torch

    from torchmeshmetric import EmptyInputError
    from torchmeshmetric.evaluation import TemporalConsistency, evaluate_pair

    ref, coarse = trimesh.creation.icosphere(subdivisions=2), _SPHERE

    def faceless(m):
        return torch.tensor(m.vertices), torch.zeros(0, 3, dtype=torch.long)

    def identity(source, target):
        return source

    cases = {
        "simplified_k": ((faceless(coarse), ref, ref), {}),
        "original_k": ((coarse, faceless(ref), ref), {}),
        "original_k_minus_1": ((coarse, ref, faceless(ref)), {}),
        "simplified_k_minus_1": ((coarse, ref, ref), {"simplified_k_minus_1": faceless(coarse)}),
    }
    for name, (args, kwargs) in cases.items():
        with pytest.raises(EmptyInputError, match=rf"^{name}: expected a mesh with at least one face, found none"):
            evaluate_pair(*args, registration_fn=identity, **kwargs)
    with pytest.raises(EmptyInputError, match=r"^simplified_k: expected a mesh with at least one face"):
        TemporalConsistency(registration_fn=identity).update(faceless(coarse), ref, ref)
