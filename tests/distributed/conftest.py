"""Fixtures shared with the evaluation tests."""

from tests.evaluation.conftest import moving_spheres

__all__ = ["moving_spheres"]
