"""With no process group (or one rank), run_tasks keeps a task's exception type and names the task in its notes,
and the command line's error line shows it (issue 41, theme 8)."""

from __future__ import annotations

import pytest

from torchmeshmetric.launch import error_line
from torchmeshmetric.tasks import run_tasks


class FrameError(ValueError):
    pass


def _fail_on_two(x: int) -> int:
    if x == 2:
        raise FrameError("frame 2 has no faces")
    return x


def test_a_failing_task_keeps_its_type_and_is_named():
    with pytest.raises(FrameError) as info:
        run_tasks(_fail_on_two, [1, 2, 3], describe=lambda t: f"frame pair {t - 1} -> {t}")
    assert str(info.value) == "frame 2 has no faces"  # its own message, unchanged
    assert info.value.__notes__ == ["while running frame pair 1 -> 2"]
    line = error_line("ctc", info.value)
    assert line == "torchmeshmetric ctc: error: frame 2 has no faces (while running frame pair 1 -> 2)"


def test_a_task_that_is_rerun_is_named_once():
    err = FrameError("again")
    for _ in range(2):
        with pytest.raises(FrameError) as info:
            run_tasks(lambda x: (_ for _ in ()).throw(err), [0], describe=lambda t: "the task")
    assert info.value.__notes__ == ["while running the task"]
