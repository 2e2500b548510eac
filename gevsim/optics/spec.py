"""Build :class:`Lens` and :class:`Pixel` from a TOML-like table."""

from __future__ import annotations

from gevsim.errors import ConfigError, check_keys
from gevsim.optics.lens import Lens
from gevsim.optics.sensor import Pixel

__all__ = ["OPTICS_KEYS", "from_spec"]

_LENS_KEYS = ("f_number", "transmission", "focal_length_m")
_PIXEL_KEYS = ("pitch_m", "fill_factor", "qe")
#: Keys accepted by :func:`from_spec`.
OPTICS_KEYS = _LENS_KEYS + _PIXEL_KEYS


def from_spec(spec: dict, *, source: str | None = None, where: str = "optics") -> tuple[Lens, Pixel]:
    """(Lens, Pixel) from a table such as a TOML ``[optics]`` section.

    Keys (all optional; missing ones take the dataclass defaults):
    ``f_number``, ``transmission``, ``focal_length_m``, ``pitch_m``,
    ``fill_factor`` and ``qe`` (a number, or a table
    ``{wavelength_nm = [...], qe = [...]}``).

    Raises
    ------
    ConfigError
        Unknown key (with a suggestion) or a bad value, naming ``source`` and
        the key.
    """
    if not isinstance(spec, dict):
        raise ConfigError(f"expected a table, got {type(spec).__name__}", source=source, key=where)
    check_keys(spec, OPTICS_KEYS, source=source, where=where)
    qe = spec.get("qe")
    if isinstance(qe, dict):
        check_keys(qe, ("wavelength_nm", "qe"), source=source, where=f"{where}.qe")
        if "wavelength_nm" not in qe or "qe" not in qe:
            raise ConfigError(
                "qe table needs 'wavelength_nm' and 'qe' lists", source=source, key=f"{where}.qe"
            )
        qe = (qe["wavelength_nm"], qe["qe"])
    parts: list[Lens | Pixel] = []
    for cls, keys in ((Lens, _LENS_KEYS), (Pixel, _PIXEL_KEYS)):
        kwargs = {k: spec[k] for k in keys if k in spec}
        if "qe" in kwargs:
            kwargs["qe"] = qe
        try:
            parts.append(cls(**kwargs))
        except (TypeError, ValueError) as exc:
            key = next((k for k in kwargs if str(exc).startswith(k)), None)
            raise ConfigError(str(exc), source=source, key=f"{where}.{key}" if key else where) from exc
    lens, pixel = parts
    assert isinstance(lens, Lens) and isinstance(pixel, Pixel)
    return lens, pixel
