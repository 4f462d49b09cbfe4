import pytest

from tests.evaluation.eval_helpers import sphere


@pytest.fixture
def moving_spheres():
    """4 original frames (icosphere 2, translated 0.1 per frame) and their 'simplified' frames (icosphere 1)."""
    original = [sphere(2, offset=(0.1 * k, 0, 0)) for k in range(4)]
    simplified = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(4)]
    return original, simplified
