"""``torchmeshmetric.mpeg``'s rooms import one way: core, then sampling, then comparison, then ctc.

A module may import its own room and the rooms before it, never one after it (docs/architecture.md draws them).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import torchmeshmetric.mpeg

MPEG = Path(torchmeshmetric.mpeg.__file__).parent
ROOMS = ("core", "sampling", "comparison", "ctc")


def _imported_rooms(path: Path) -> set[str]:
    """The rooms of ``torchmeshmetric.mpeg`` a module imports (at the top or inside a function)."""
    rooms = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] if node.level == 0 else []
            assert node.level == 0, f"{path.name}: relative import"
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        for name in names:
            parts = name.split(".")
            if parts[:2] == ["torchmeshmetric", "mpeg"] and len(parts) > 2:
                rooms.add(parts[2])
    return rooms


@pytest.mark.parametrize("room", ROOMS)
def test_a_room_imports_only_itself_and_the_rooms_before_it(room):
    allowed = set(ROOMS[: ROOMS.index(room) + 1])
    modules = sorted((MPEG / room).glob("*.py"))
    assert len(modules) > 1, room
    for module in modules:
        assert _imported_rooms(module) <= allowed, (module.name, _imported_rooms(module) - allowed)


def test_every_module_lives_in_a_room():
    assert sorted(p.name for p in MPEG.glob("*.py")) == ["__init__.py"]
    assert sorted(p.name for p in MPEG.iterdir() if p.is_dir() and p.name != "__pycache__") == sorted(ROOMS)
