import pytest

from tests.cli.cli_helpers import Counting, write_frames


@pytest.fixture
def known_registration(monkeypatch):
    """Replace the default (non-rigid) registration by the exact one so CLI tests test the CLI, fast."""
    fn = Counting()
    monkeypatch.setattr("torchmeshmetric.evaluation.pipeline.default_register", fn)
    monkeypatch.setattr("torchmeshmetric.evaluation.default_register", fn)
    return fn


@pytest.fixture
def sequence(tmp_path):
    return write_frames(tmp_path / "orig", 2), write_frames(tmp_path / "simp", 1)
