"""The runnable examples of docs/api.md (examples/*.py) run, in the order the page gives, and write what
they say they write."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ORDER = ["emulate_scene.py", "frames_to_events.py", "export_and_view.py"]


def test_every_example_runs_and_writes_its_outputs(tmp_path, monkeypatch, capsys):
    assert sorted(p.name for p in (ROOT / "examples").glob("*.py")) == sorted(ORDER)  # none left untested
    monkeypatch.chdir(ROOT)
    for name in ORDER:
        monkeypatch.setattr(sys, "argv", [name, str(tmp_path)])
        runpy.run_path(str(ROOT / "examples" / name), run_name="__main__")
    for written in ("office.h5", "bar.h5", "office.txt", "office.npz", "office.gif"):
        assert (tmp_path / written).stat().st_size > 0, written
    table = np.loadtxt(tmp_path / "office.txt", comments="#", ndmin=2)
    assert table.shape[1] == 4 and np.all(np.diff(table[:, 0]) >= 0)
    assert "reconstructed" in capsys.readouterr().out
    api = (ROOT / "docs" / "api.md").read_text()
    assert all(f"examples/{name}" in api for name in ORDER)  # the page names each one
