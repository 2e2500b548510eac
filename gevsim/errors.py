"""Exceptions shared by every stage.

Library code raises :class:`ConfigError` (a ``ValueError``) for bad user input
and :class:`MissingExtraError` (an ``ImportError``) for an optional extra that is
not installed. Both are :class:`GevsimError`: the CLI prints them as one clear
line and exits with code 2; anything else is a bug and shows its traceback.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class GevsimError(Exception):
    """Base of gevsim's own errors: bad input or a missing extra, never a bug."""


class MissingExtraError(GevsimError, ImportError):
    """An optional extra is not installed; the message says what to install."""


class ConfigError(GevsimError, ValueError):
    """Bad user input: names the file (``source``) and ``key`` it concerns."""

    def __init__(self, message: str, *, source: str | None = None, key: str | None = None):
        self.source = source
        self.key = key
        where = ": ".join(part for part in (source, key) if part)
        super().__init__(f"{where}: {message}" if where else message)


def suggest(name: str, choices: Iterable[str]) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest of ``choices``, or ``""``."""
    close = difflib.get_close_matches(name, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def clipped(text: str, limit: int = 80) -> str:
    """``text`` cut to ``limit`` characters for a one-line message (a 4,000-character path stays readable)."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def check_keys(table: dict, allowed: Iterable[str], *, source: str | None, where: str) -> None:
    """Raise :class:`ConfigError` for the first key of ``table`` not in ``allowed``."""
    allowed = list(allowed)
    for key in table:
        if key not in allowed:
            raise ConfigError(
                f"unknown key {key!r}{suggest(key, allowed)}; allowed: {', '.join(sorted(allowed))}",
                source=source,
                key=f"{where}.{key}" if where else key,
            )


def one_line(message: object, *, last: bool = False) -> str:
    """Another library's (multi-line) message as one line: its first line and how many more there
    were; with ``last``, also its last line (a nested error's innermost cause, as in Mitsuba's include chain)."""
    lines = [line.strip() for line in str(message).splitlines() if line.strip()]
    if len(lines) <= 1:
        return lines[0] if lines else ""
    if not last:
        return f"{lines[0]} [{len(lines) - 1} more lines]"
    between = f" [{len(lines) - 2} more lines]" if len(lines) > 2 else ""
    return f"{lines[0]} ...{between} {lines[-1]}"
