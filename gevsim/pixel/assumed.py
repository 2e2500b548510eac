"""The plausible range of each assumed number of a sensor preset (issue 35, item 3).

A preset marks the numbers no source gives with a comment ``# assumed``. Its optional ``[assumed.<table>]``
tables give each of them the ends a study may sweep it to (``gevsim study``'s ``[sensitivity]``, a tornado
plot of how far the headline answer moves) and the reason for them::

    [assumed.noise]
    dc_offset_v = { range = [0.0, 4e-3], why = "Pelgrom mismatch of the feedback transistors: ..." }
    [assumed.sensor]
    quantum_efficiency = { values = ["fsi", "bsi"], why = "..." }  # a categorical assumption: its alternatives

An entry is named by the table and the field it ranges over, which must be a key of that table in the same
file (the preset's own value must lie in the range or among the values). :func:`parse_assumed` reads the raw
``assumed`` table; :func:`gevsim.pixel.presets.with_overrides` takes the same qualified names
(``"noise.dc_offset_v"``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from gevsim.errors import ConfigError, suggest

#: The preset tables an assumption may range over.
ASSUMED_TABLES = ("sensor", "photoreceptor", "noise", "events", "readout", "aps")
#: The ``[sensor]`` keys a study can vary (the others name the chip or size its informational array).
SENSOR_FIELDS = ("pixel_pitch_m", "fill_factor", "quantum_efficiency", "bandwidth_reference_spectrum")
ENTRY_KEYS = ("range", "values", "why")


@dataclasses.dataclass(frozen=True)
class Assumed:
    """One assumed number of a preset and its plausible range.

    Parameters
    ----------
    key : ``"table.field"``, e.g. ``"noise.dc_offset_v"`` (a key :func:`~gevsim.pixel.presets.with_overrides`
        takes).
    value : the preset's own value of that field, as written in the file.
    why : the reason for the range (a physical argument or a published scatter).
    low, high : the ends of a numeric range (None for a categorical assumption).
    values : the alternatives of a categorical assumption (the preset's value among them); ``()`` for a range.
    """

    key: str
    value: Any
    why: str
    low: float | None = None
    high: float | None = None
    values: tuple = ()

    def ends(self) -> tuple:
        """What a sweep tries: ``(low, high)`` for a range, else the alternatives other than ``value``."""
        if self.values:
            return tuple(v for v in self.values if v != self.value)
        return (self.low, self.high)


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _entry(key: str, entry: Any, value: Any, *, source: str | None) -> Assumed:
    """One ``field = { range = [...] | values = [...], why = "..." }`` of an ``[assumed.<table>]``."""

    def fail(message: str) -> ConfigError:
        return ConfigError(message, source=source, key=f"assumed.{key}")

    if not isinstance(entry, dict):
        raise fail(f"expected a table {{ range = [low, high], why = \"...\" }} or {{ values = [...], why = \"...\" }}, "
                   f"got {entry!r}")
    for name in entry:
        if name not in ENTRY_KEYS:
            raise fail(f"unknown key {name!r}{suggest(name, ENTRY_KEYS)}; allowed: {', '.join(ENTRY_KEYS)}")
    why = entry.get("why")
    if not isinstance(why, str) or not why.strip():
        raise fail(f"'why' must be a non-empty string saying where the range comes from, got {why!r}")
    if ("range" in entry) == ("values" in entry):
        raise fail("give exactly one of 'range' (two numbers) and 'values' (the alternatives)")
    if "values" in entry:
        values = entry["values"]
        if not isinstance(values, list) or not values:
            raise fail(f"'values' must be a non-empty list of the alternatives, got {values!r}")
        if value not in values:
            raise fail(f"'values' {values!r} must contain the preset's own value {value!r}")
        return Assumed(key=key, value=value, why=why.strip(), values=tuple(values))
    bounds = entry["range"]
    if not (isinstance(bounds, list) and len(bounds) == 2 and all(_number(b) for b in bounds)):
        raise fail(f"'range' must be two finite numbers [low, high], got {bounds!r}")
    low, high = float(bounds[0]), float(bounds[1])
    if not low < high:
        raise fail(f"'range' needs low < high, got {bounds!r}")
    if not _number(value):
        raise fail(f"the preset's value {value!r} is not a number: give its alternatives as 'values'")
    if not low <= value <= high:
        raise fail(f"the preset's own value {value!r} lies outside 'range' [{low:g}, {high:g}]")
    return Assumed(key=key, value=value, why=why.strip(), low=low, high=high)


def parse_assumed(assumed: Any, raw: dict, *, source: str | None = None) -> dict[str, Assumed]:
    """The :class:`Assumed` entries of a preset's raw ``assumed`` table, by ``"table.field"``.

    Parameters
    ----------
    assumed : the parsed ``[assumed]`` table (``{"noise": {"dc_offset_v": {...}}}``), or None.
    raw : the whole parsed preset file, whose tables hold the values the entries range over.
    source : the file, named in errors.

    Raises
    ------
    ConfigError
        Naming ``assumed.<table>.<field>``: an unknown table, a field the file's table does not set, a range
        without the preset's value, both or neither of ``range``/``values``, an empty ``why``, an unknown key.
    """
    if assumed is None:
        return {}
    if not isinstance(assumed, dict):
        raise ConfigError(f"expected tables [assumed.<table>], got {assumed!r}", source=source, key="assumed")
    out: dict[str, Assumed] = {}
    for table, entries in assumed.items():
        if table not in ASSUMED_TABLES:
            raise ConfigError(f"unknown table {table!r}{suggest(table, ASSUMED_TABLES)}; allowed: "
                              f"{', '.join(ASSUMED_TABLES)}", source=source, key=f"assumed.{table}")
        if not isinstance(entries, dict):
            raise ConfigError(f"expected a table, got {entries!r}", source=source, key=f"assumed.{table}")
        written = raw.get(table)
        written = written if isinstance(written, dict) else {}
        for field, entry in entries.items():
            if field not in written:
                raise ConfigError(f"[{table}] of this file sets no {field!r}{suggest(field, written)}: an assumption "
                                  "ranges over a value the file gives", source=source, key=f"assumed.{table}.{field}")
            if table == "sensor" and field not in SENSOR_FIELDS:
                raise ConfigError(f"sensor.{field} cannot be varied; a study varies {', '.join(SENSOR_FIELDS)}",
                                  source=source, key=f"assumed.{table}.{field}")
            out[f"{table}.{field}"] = _entry(f"{table}.{field}", entry, written[field], source=source)
    return out
