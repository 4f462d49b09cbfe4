"""Imports cost only what is used: the modules a fresh process holds after each entry point (not a timing).

``import torchmeshmetric`` and ``import torchmeshmetric.cli`` load none of the heavy packages (the package's names
load on first use, ``torchmeshmetric/_lazy.py``); ``torchmeshmetric --help`` and ``torchmeshmetric COMMAND --help``
load no torch (the command table, ``torchmeshmetric/cli/__init__.py``); a name loads what its own module needs and
no more. Each case runs in a fresh interpreter, since this test process has imported everything already.
"""

from __future__ import annotations

import ast
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from torchmeshmetric.cli import COMMANDS

REPO = Path(__file__).resolve().parents[1]

#: Heavy packages that none of the start-up entry points may load (torch alone is ~2 s of a 2-core machine's start-up,
#: torchmetrics ~1.3 s of which scipy.signal ~0.8 s; `python -X importtime -c "import torchmeshmetric"` in issue 22).
HEAVY = ("torch", "torchmetrics", "scipy", "matplotlib", "kornia", "skimage", "trimesh", "numpy", "triton")
#: What the torchmetrics-based classes alone pull in, which the rest of the library must not.
METRICS_ONLY = ("torchmetrics", "scipy", "matplotlib")


def _modules(code: str) -> set[str]:
    """The modules in ``sys.modules`` (full names and their top-level packages) after ``code``, in a fresh process."""
    script = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)), file=sys.stderr)\n"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    env.pop("EAGER_IMPORT", None)  # lazy_loader's switch to import everything at once
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=REPO, check=False)
    assert r.returncode == 0, r.stderr
    names = json.loads(r.stderr.splitlines()[-1])
    return set(names) | {name.split(".")[0] for name in names}


def _help(*args: str) -> str:
    """``torchmeshmetric ARGS --help`` as a script (argparse ends it with SystemExit after printing the help)."""
    argv = [*args, "--help"]
    return f"from torchmeshmetric.cli import main\ntry:\n    main({argv!r})\nexcept SystemExit:\n    pass"


@pytest.mark.parametrize(
    "code",
    [
        "import torchmeshmetric",
        "import torchmeshmetric.cli",
        "import torchmeshmetric.data, torchmeshmetric.evaluation, torchmeshmetric.kernels.accel",
        "import torchmeshmetric.metrics, torchmeshmetric.mpeg, torchmeshmetric.registration",
        "import torchmeshmetric.simplification, torchmeshmetric.stats, torchmeshmetric.viz",
    ],
)
def test_importing_the_package_loads_no_heavy_package(code):
    loaded = _modules(code)
    assert [p for p in HEAVY if p in loaded] == []


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_help_loads_no_torch_and_only_the_command_asked_for(command):
    loaded = _modules(_help() if command is None else _help(command))
    assert [p for p in HEAVY if p in loaded] == []
    modules = {COMMANDS[c].module_path for c in COMMANDS}
    wanted = set() if command is None else {COMMANDS[command].module_path}
    assert modules & loaded == wanted


@pytest.mark.parametrize(
    ("name", "absent"),
    [
        ("Mesh", METRICS_ONLY),
        ("point_mesh_distance", METRICS_ONLY),
        ("distance_statistics", METRICS_ONLY),
        ("load_mesh", METRICS_ONLY),
        ("MeshSurfaceDistanceLoss", METRICS_ONLY),  # a training script that wants a loss
        ("nearest_vertex_distance_loss", METRICS_ONLY),
        ("mesh_surface_distance_sets", METRICS_ONLY),
        ("evaluate_sequence", METRICS_ONLY),
        ("MeshSurfaceDistance", ()),  # a torchmetrics.Metric: torchmetrics loads with it, on first use
    ],
)
def test_a_name_loads_on_first_use_with_what_its_module_needs(name, absent):
    loaded = _modules(f"import torchmeshmetric\ntorchmeshmetric.{name}")
    assert "torch" in loaded
    assert [p for p in absent if p in loaded] == []
    if name == "MeshSurfaceDistance":
        assert "torchmetrics" in loaded


def _run_time_imports(module_path: str) -> list[str]:
    """The modules a command module imports inside its functions (its ``run`` imports them when it starts)."""
    tree = ast.parse(Path(importlib.util.find_spec(module_path).origin).read_text())
    found = [module_path]
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            found += [n.module for n in ast.walk(node) if isinstance(n, ast.ImportFrom) and n.module]
    return found


@pytest.mark.parametrize("command", ["evaluate", "compare", "campaign", "simplify", "register", "validate"])
def test_a_command_loads_no_torchmetrics(command):
    """What running the command imports: its module, what its functions import, the launcher (``main``)."""
    modules = [*_run_time_imports(COMMANDS[command].module_path), "torchmeshmetric.launch"]
    assert len(modules) > 3
    loaded = _modules("import " + ", ".join(modules))
    assert "torch" in loaded
    assert [p for p in METRICS_ONLY if p in loaded] == []
