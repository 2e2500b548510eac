"""Does the running environment hold the locked versions (``requirements.lock``)?

The repository's ``requirements.lock`` lists the exact version of every package the ``.venv`` of
``make demo`` / ``make test`` gets (``make lock`` regenerates it). Bit-identical results are
promised for the same locked versions on any x86-64 CPU (README, Reproducibility); ``gevsim info``
says whether this environment is one of them.
"""

from __future__ import annotations

import re
from importlib import metadata
from pathlib import Path

LOCK_NAME = "requirements.lock"
_LINE = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)(?:\[[^\]]*\])?==([^\s;#]+)")


def lock_path() -> Path | None:
    """The lock file of the source tree this gevsim runs from, or None (e.g. installed from a wheel)."""
    p = Path(__file__).resolve().parents[1] / LOCK_NAME
    return p if p.is_file() else None


def read_lock(path: Path) -> dict[str, str]:
    """``{normalised name: version}`` from a ``name==version`` file (comments, options skipped)."""
    pins = {}
    for number, line in enumerate(path.read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith(("#", "-")):
            continue
        m = _LINE.match(line)
        if m is None:
            raise ValueError(f"{path}:{number}: expected 'name==version', got {line!r}")
        pins[normalise(m.group(1))] = m.group(2)
    return pins


def normalise(name: str) -> str:
    """PEP 503 normalised project name."""
    return re.sub(r"[-_.]+", "-", name).lower()


def _release(version: str) -> str:
    """A version without its local label: torch's CPU wheel ``2.13.0+cpu`` is the locked release ``2.13.0``."""
    return version.partition("+")[0]


def compare(pins: dict[str, str]) -> tuple[list[str], list[str]]:
    """(differences, missing): ``'name installed X, locked Y'`` and the locked names not installed."""
    installed = {normalise(d.metadata["Name"]): d.version for d in metadata.distributions() if d.metadata["Name"]}
    differ = [f"{n} {installed[n]} (locked {v})" for n, v in sorted(pins.items())
              if n in installed and installed[n] != v and _release(installed[n]) != v]
    missing = [n for n in sorted(pins) if n not in installed]
    return differ, missing


def status() -> str:
    """One line for ``gevsim info``."""
    path = lock_path()
    if path is None:
        return f"no {LOCK_NAME} beside this installation (not a source checkout): versions are not locked"
    try:
        pins = read_lock(path)
    except (OSError, ValueError) as exc:
        return f"cannot read {path}: {exc}"
    differ, missing = compare(pins)
    if not differ and not missing:
        return f"matches {path.name} ({len(pins)} packages)"
    parts = []
    if differ:
        parts.append(f"{len(differ)} differ: " + ", ".join(differ[:8]) + (" ..." if len(differ) > 8 else ""))
    if missing:
        parts.append(f"{len(missing)} not installed: " + ", ".join(missing[:8]) + (" ..." if len(missing) > 8 else ""))
    return f"does NOT match {path.name} ({'; '.join(parts)}); pinned outputs may differ (make test rebuilds .venv)"
