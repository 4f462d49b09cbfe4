"""Captured-like frames (duplicate vertices on open seams, zero-length edges, zero-area and unreferenced elements, thin
parts, real non-rigid motion): the registration is as repeatable there as on clean frames (issue 32), and its
convergence report tells a truncated schedule from a converged one (issue 29)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import torch

from tests.registration.gt_pairs import GTPair, make_captured_pair
from tests.registration.stability import stability
from torchmeshmetric import Mesh
from torchmeshmetric.registration import DEFAULT_SCHEDULE, NonRigidOptions, register_nonrigid
from torchmeshmetric.registration._common import welded_faces


@pytest.fixture(scope="module")
def pair() -> GTPair:
    return make_captured_pair("medium", 0.035)  # ~3k vertices, every defect of captured frames


@pytest.fixture(scope="module")
def results(pair: GTPair) -> dict[str, dict[str, Any]]:
    return stability(pair.target, pair.source, perturbations=("ulp+", "ulp-"))


@pytest.mark.parametrize("case", ["ulp+", "ulp-"])
def test_one_ulp_moves_a_captured_like_registration_by_as_little(results: dict[str, Any], case: str) -> None:
    # Goal 1e-5. Measured (2026-12-03): <= 4.4e-11 of the diagonal for the vertices and <= 1e-10 relative for every
    # statistic. Before, 1.2e-4 and 2.2e-4: a midpoint vertex of a collinear face entered or left the data points
    # with the last bit of its area, and the interpolated normal jumped across a seam of duplicate vertices.
    r = results[case]
    assert r["converged"]
    assert r["verts"] <= 1e-5
    for name, change in r["sets"].items():
        assert change <= 1e-5, (name, change)


def test_thread_counts_give_the_same_captured_like_registration(results: dict[str, Any]) -> None:
    r = results["threads=2"]
    assert r["verts"] == 0.0
    assert all(change == 0.0 for change in r["sets"].values())


def test_rounding_level_faces_have_no_normal_whatever_the_last_bits() -> None:
    # A collinear face (a, midpoint, b) has a computed area of 0 or of rounding noise depending on the last bits; a
    # thin but real face (height 1e-9 of its edge, far above rounding) keeps its normal.
    a, b = np.array([0.3, -0.7, 0.11]), np.array([0.9, 0.2, -0.4])
    c = np.array([0.1, 0.5, 0.6])
    for shift in (0.0, 1e-9, 1e-6):
        base = np.stack([a, b, c, 0.5 * (a + b), a + 0.37 * (b - a)]) * (1 + shift)
        for verts in (base, np.nextafter(base, np.inf), np.nextafter(base, -np.inf)):
            thin = verts[4] + 1e-9 * np.cross(b - a, c - a) / np.linalg.norm(np.cross(b - a, c - a))
            v = torch.from_numpy(np.concatenate([verts, thin[None]]))
            m = Mesh(v, torch.tensor([[0, 1, 2], [0, 3, 1], [0, 1, 5]]))
            assert m.surface_face_mask().tolist() == [True, False, True]
            assert m.surface_vertex_mask().tolist() == [True, True, True, False, False, True]


def test_welded_faces_point_duplicates_to_one_vertex() -> None:
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0, 0], [5, 5, 5]], dtype=torch.float64)
    f = torch.tensor([[0, 1, 2], [4, 2, 3], [3, 4, 5]])
    assert welded_faces(v, f).tolist() == [[0, 1, 2], [0, 2, 1], [1, 0, 5]]


def test_a_truncated_schedule_is_reported_not_converged(pair: GTPair) -> None:
    # Issue 29: with the old criterion (the last window's change relative to the last stage's *first* loss, 1e-2) a
    # schedule cut after stage 2 reported converged=True on the ~20k-vertex captured-like pair (4.3e-3). Measured
    # (2026-12-03, the five benchmark pairs): the default schedule ends at <= 1.2e-4 of its final loss, schedules cut
    # after stage 1, 2 or 3 at >= 1.6e-3 (tolerance 4e-4).
    gen = torch.Generator
    full = register_nonrigid(pair.source, pair.target, generator=gen().manual_seed(0))
    assert full.converged, full.reason
    for n in (1, 2, 3):
        cut = register_nonrigid(
            pair.source, pair.target, schedule=DEFAULT_SCHEDULE[:n], generator=gen().manual_seed(0), warn=False
        )
        assert not cut.converged and cut.reason.startswith("not converged"), (n, cut.reason)
    # Annealing the cut schedule's last stage as the default's last one makes it converged, as the docs say.
    annealed = (*DEFAULT_SCHEDULE[:1], DEFAULT_SCHEDULE[1]._replace(lr_decay=1e-3, max_steps=80))
    r = register_nonrigid(pair.source, pair.target, schedule=annealed, generator=gen().manual_seed(0))
    assert r.converged, r.reason


def test_adam_eps_is_an_option() -> None:
    assert NonRigidOptions().adam_eps == 1e-6
    with pytest.raises(ValueError, match="adam_eps"):
        NonRigidOptions(adam_eps=-1.0)
    assert NonRigidOptions(adam_eps=1e-5) != NonRigidOptions()
