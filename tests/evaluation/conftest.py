import importlib.util

import pytest

from tests.evaluation.eval_helpers import sphere

# The pipeline summarises every set with issue 3's distance_statistics; until that branch is merged here,
# every test of this folder is skipped (the module does not exist on this branch yet).
HAS_STATS = importlib.util.find_spec("torchmeshmetric.stats") is not None
collect_ignore_glob = [] if HAS_STATS else ["test_*.py"]


@pytest.fixture
def moving_spheres():
    """4 original frames (icosphere 2, translated 0.1 per frame) and their 'simplified' frames (icosphere 1)."""
    original = [sphere(2, offset=(0.1 * k, 0, 0)) for k in range(4)]
    simplified = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(4)]
    return original, simplified
