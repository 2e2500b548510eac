"""Registry of waveform types and the factory that builds one from a config table.

A lamp type is its module (a frozen dataclass :class:`~gevsim.illumination.base.Waveform` whose
fields are its config keys, checked in ``__post_init__``) plus one entry in :data:`WAVEFORMS`.
Studies sweep the types that define :meth:`~gevsim.illumination.base.Waveform.swept` and datasets
draw those that define :meth:`~gevsim.illumination.base.Waveform.drawn` (:data:`SWEPT_WAVEFORMS`,
:data:`RANDOM_WAVEFORMS`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import ConfigError, check_keys, suggest
from .base import DC, FieldError, RandomRanges, Waveform
from .basic import PWM, Sinusoid
from .mains import Fluorescent, Incandescent, SodiumHID
from .table import Table

__all__ = ["RANDOM_WAVEFORMS", "SWEPT_WAVEFORMS", "WAVEFORMS", "from_spec", "random_spec", "swept_spec"]

#: Waveform classes by the ``type`` name used in config files.
WAVEFORMS: dict[str, type[Waveform]] = {
    "dc": DC,
    "sinusoid": Sinusoid,
    "pwm": PWM,
    "fluorescent": Fluorescent,
    "incandescent": Incandescent,
    "sodium_hid": SodiumHID,
    "table": Table,
}


def _defines(cls: type[Waveform], method: str) -> bool:
    return getattr(cls, method).__func__ is not getattr(Waveform, method).__func__


#: The types a study sweeps (the registry's order).
SWEPT_WAVEFORMS: tuple[str, ...] = tuple(name for name, cls in WAVEFORMS.items() if _defines(cls, "swept"))
#: The types a dataset draws from (the registry's order).
RANDOM_WAVEFORMS: tuple[str, ...] = tuple(name for name, cls in WAVEFORMS.items() if _defines(cls, "drawn"))


def swept_spec(name: str, frequency_hz: float, params: Mapping[str, Any]) -> dict[str, Any]:
    """The config table of lamp type ``name`` (one of :data:`SWEPT_WAVEFORMS`) whose light flickers at
    ``frequency_hz`` in a study run with sweep values ``params`` (:meth:`Waveform.swept`)."""
    return {"type": name, **WAVEFORMS[name].swept(frequency_hz, params)}


def random_spec(name: str, rng: np.random.Generator, ranges: RandomRanges, *, phase_rad: float) -> dict[str, Any]:
    """A random config table of lamp type ``name`` (one of :data:`RANDOM_WAVEFORMS`) drawn with ``rng``
    from ``ranges`` (:meth:`Waveform.drawn`)."""
    return {"type": name, **WAVEFORMS[name].drawn(rng, ranges, phase_rad=phase_rad)}


def from_spec(spec: Mapping[str, Any], *, source: str | None = None, key: str = "waveform") -> Waveform:
    """Build a waveform from a config table such as ``{"type": "pwm", "frequency_hz": 200, "duty": 0.3}``.

    Parameters
    ----------
    spec : mapping
        ``spec["type"]`` is a key of :data:`WAVEFORMS`; the other keys are
        that class's dataclass fields.
    source : str, optional
        File the table came from, for error messages.
    key : str
        Dotted key of the table in that file, for error messages.

    Raises
    ------
    ConfigError
        Unknown type or field (with a did-you-mean suggestion), missing
        required field, or an invalid value; the message names the key.
    """
    if not isinstance(spec, Mapping):
        raise ConfigError(f"expected a table with a 'type' key, got {spec!r}", source=source, key=key)
    if "type" not in spec:
        raise ConfigError(f"missing 'type'; one of: {', '.join(WAVEFORMS)}", source=source, key=key)
    name = spec["type"]
    if not isinstance(name, str) or name not in WAVEFORMS:
        hint = suggest(name, WAVEFORMS) if isinstance(name, str) else ""
        raise ConfigError(f"unknown waveform type {name!r}{hint}; one of: {', '.join(WAVEFORMS)}",
                          source=source, key=f"{key}.type")
    cls = WAVEFORMS[name]
    fields = dataclasses.fields(cls)  # type: ignore[arg-type]  # every registered waveform is a dataclass
    params = {k: v for k, v in spec.items() if k != "type"}
    check_keys(params, ["type", *(f.name for f in fields)], source=source, where=key)
    required = [f.name for f in fields
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    for field in required:
        if field not in params:
            raise ConfigError(f"missing required field {field!r} for type {name!r}",
                              source=source, key=f"{key}.{field}")
    try:
        return cls(**params)
    except FieldError as err:
        raise ConfigError(str(err), source=source, key=f"{key}.{err.field}") from None
    except (TypeError, ValueError) as err:
        raise ConfigError(str(err), source=source, key=key) from None
