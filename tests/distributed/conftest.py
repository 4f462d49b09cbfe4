"""Fixtures of the distributed tests."""

import pytest
import torch

from tests.evaluation.conftest import moving_spheres

__all__ = ["moving_spheres"]


@pytest.fixture(autouse=True)
def _restore_torch_threads():
    """Commands run here with ``--threads 1`` set this process's thread count; later tests get it back."""
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)
