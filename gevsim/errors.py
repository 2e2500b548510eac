"""Exceptions shared by every stage.

Library code raises :class:`ConfigError` (a ``ValueError``) for bad user input
so that the CLI can print one clear line and exit with code 2.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class ConfigError(ValueError):
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
