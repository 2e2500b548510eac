"""Long work is never silent (issue 35, item 5): without a terminal, progress is a line at each tenth."""

import re

from gevsim.cli._common import _progress


def test_without_a_terminal_progress_is_a_line_per_tenth(capsys):
    update, close = _progress("study demo", True, unit="job")
    for done in range(77):
        update(done, 76)
    close()
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 11 and lines[-1].startswith("study demo: 76/76 jobs (100 %)")
    assert [int(re.search(r"\((\d+) %\)", line).group(1)) // 10 for line in lines] == list(range(11))


def test_quiet_progress_prints_nothing(capsys):
    update, close = _progress("study demo", False, unit="job")
    assert update is None
    close()
    assert capsys.readouterr().err == ""
