import pytest
import torch


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """Registration tests run single-threaded: on the shared 2-core sandbox, 2 torch threads are far slower."""
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)
