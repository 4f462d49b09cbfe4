"""matplotlib and triton stay off ``import torchmeshmetric``: no module of the package imports them at load time.

torchmetrics itself imports matplotlib when it is installed, so ``sys.modules`` after ``import torchmeshmetric``
cannot tell; the module bodies are read instead (imports inside functions run on use; ``if TYPE_CHECKING:`` blocks
never run). ``kernels/accel/triton_traversal.py`` is the one module that imports triton at load, inside a
``try``, and only the ``"triton"`` backend imports that module (``test_library_works_without_triton``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "torchmeshmetric"
MODULES = sorted(PACKAGE.rglob("*.py"))
ON_USE_ONLY = {"matplotlib": set(), "triton": {"kernels/accel/triton_traversal.py"}}


def _load_time_imports(tree: ast.Module) -> set[str]:
    """Top-level package names imported when the module body runs (functions and classes bodies excluded)."""
    found: set[str] = set()
    pending: list[ast.stmt] = list(tree.body)
    while pending:
        node = pending.pop()
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
        elif isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            pending.extend(node.orelse)
        elif isinstance(node, ast.If | ast.Try | ast.With):
            for field in ("body", "orelse", "finalbody", "handlers"):
                pending.extend(getattr(node, field, []))
        elif isinstance(node, ast.ExceptHandler):
            pending.extend(node.body)
    return found


def test_the_package_is_read():
    assert len(MODULES) > 50
    assert "matplotlib" not in _load_time_imports(ast.parse("def f():\n    import matplotlib\n"))
    guarded = "try:\n    import matplotlib.pyplot as plt\nexcept ImportError:\n    plt = None\n"
    assert "matplotlib" in _load_time_imports(ast.parse(guarded))
    assert "triton" not in _load_time_imports(ast.parse("if TYPE_CHECKING:\n    import triton\n"))


@pytest.mark.parametrize("package", sorted(ON_USE_ONLY))
def test_optional_packages_are_imported_on_use_only(package):
    offenders = [
        str(path.relative_to(PACKAGE))
        for path in MODULES
        if package in _load_time_imports(ast.parse(path.read_text()))
        and str(path.relative_to(PACKAGE)) not in ON_USE_ONLY[package]
    ]
    assert offenders == [], f"{package} imported at load time by {offenders}"
