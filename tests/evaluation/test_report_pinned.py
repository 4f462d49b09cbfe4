"""The demo's report, pinned: a small demo run must write exactly the golden report.json, report.csv and report.md.

The demo runs the whole chain (built-in sequence, registration, QEM and Registered QEM, the four sets and their
statistics, report writers), so any refactoring that changes a number or a field of the report fails here.

Normalised before comparing (they legitimately differ from run to run), and nothing else:

* ``version``: the installed package's version, which changes with every release;
* ``methods.<name>.pairs[*].timings``: wall-clock seconds of each step (the keys are kept and compared, only the
  values are replaced).

The run uses one torch thread and float64 so that the floats are the same on every machine (parallel reductions
may round differently with another thread count), and they are compared exactly as written in the JSON.

Regenerate the golden files (only when a change of the report is intended, and say so in the commit) with::

    python -m tests.evaluation.test_report_pinned
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import torch

from torchmeshmetric.cli import main

GOLDEN = Path(__file__).parent / "golden" / "demo_report"
ARGS = [
    "demo",
    "--frames", "3",
    "--resolution", "24",
    "--target", "0.5",
    "--registration", "fast",
    "--weights", "none",
    "--no-plots",
    "--threads", "1",
    "--dtype", "float64",
]  # fmt: skip
FILES = ("report.json", "report.csv", "report.md")
VARYING = "<varies>"


def normalise(report: dict[str, Any]) -> dict[str, Any]:
    """The report with the fields that vary between runs replaced by a placeholder (see the module docstring)."""
    report = json.loads(json.dumps(report))  # a deep copy
    report["version"] = VARYING
    for method in report["methods"].values():
        for pair in method["pairs"]:
            pair["timings"] = dict.fromkeys(pair["timings"], VARYING)
    return report


def run_demo(out_dir: Path) -> dict[str, str]:
    """Run the pinned demo into ``out_dir``; the text of each report file (report.json normalised)."""
    threads = torch.get_num_threads()
    try:
        code = main([*ARGS, "--out-dir", str(out_dir)])
    finally:
        torch.set_num_threads(threads)  # --threads 1 sets it for the whole (test) process
    assert code == 0
    texts = {name: (out_dir / name).read_text() for name in FILES}
    texts["report.json"] = json.dumps(normalise(json.loads(texts["report.json"])), indent=2) + "\n"
    return texts


def test_demo_report_equals_golden(tmp_path, capsys):
    texts = run_demo(tmp_path / "demo")
    capsys.readouterr()
    for name in FILES:
        golden = (GOLDEN / name).read_text()
        if name == "report.json":  # compared as data first: a failure then names the field
            assert json.loads(texts[name]) == json.loads(golden)
        assert texts[name] == golden, name


def test_normalise_keeps_everything_but_version_and_timings():
    report = {
        "version": "1.2.3",
        "settings": {"dtype": "float64"},
        "methods": {"A": {"pairs": [{"frame": 1, "surface_k": {"ave": 0.5}, "timings": {"distances": 0.25}}]}},
    }
    out = normalise(report)
    assert out == {
        "version": VARYING,
        "settings": {"dtype": "float64"},
        "methods": {"A": {"pairs": [{"frame": 1, "surface_k": {"ave": 0.5}, "timings": {"distances": VARYING}}]}},
    }
    assert report["version"] == "1.2.3"  # the caller's report is left alone


if __name__ == "__main__":  # regenerate the golden files
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        written = run_demo(Path(tmp) / "demo")
    GOLDEN.mkdir(parents=True, exist_ok=True)
    for name, text in written.items():
        (GOLDEN / name).write_text(text)
    print(f"wrote {', '.join(str(GOLDEN / n) for n in FILES)}", file=sys.stderr)
