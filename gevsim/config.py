"""Reading TOML configuration: files, typed values, and the folders of shipped
resources (``scenes/``, ``noise/``). Every error names the file and the key."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Sequence
from dataclasses import fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, NoReturn, Self

from gevsim import _validate
from gevsim._validate import FieldError  # defined with the checks that raise it; re-exported here
from gevsim.errors import ConfigError, check_keys

__all__ = ["FieldError", "FromTable", "TomlReader", "load_table", "read_toml", "resolve_relative", "resource_tomls"]

_REPO = Path(__file__).resolve().parents[1]
_PACKAGE = Path(__file__).resolve().parent


def resource_tomls(kind: str) -> dict[str, Path]:
    """The TOML files of a shipped resource folder (``scenes`` or ``noise``), by stem.

    Looks in the source tree (``<repo>/<kind>``) and in an installed wheel
    (``gevsim/_<kind>``).
    """
    found = {}
    for folder in (_PACKAGE / f"_{kind}", _REPO / kind):
        if folder.is_dir():
            found.update({p.stem: p for p in sorted(folder.glob("*.toml"))})
    return found


class FromTable:
    """Mixin for parameter dataclasses: build one from a TOML table ``[TABLE]``.

    Validation in ``__post_init__`` raises :class:`FieldError`; here it becomes a
    :class:`ConfigError` naming the file and ``TABLE.field``.
    """

    TABLE = ""
    if TYPE_CHECKING:  # every subclass is a dataclass
        __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]

    @classmethod
    def from_table(cls, table: dict, *, source: str | None = None, where: str | None = None,
                   base: Self | None = None) -> Self:
        """An instance from ``table``; missing keys take the dataclass defaults, or those of ``base``."""
        where = cls.TABLE if where is None else where
        if not isinstance(table, dict):
            raise ConfigError(f"expected a table, got {table!r}", source=source, key=where)
        check_keys(table, [f.name for f in fields(cls)], source=source, where=where)
        try:
            return cls(**table) if base is None else dataclasses.replace(base, **table)
        except FieldError as err:
            raise ConfigError(str(err), source=source, key=f"{where}.{err.field}" if where else err.field) from None

    @classmethod
    def from_section(cls, table: dict, *, source: str | None = None, where: str | None = None,
                     base: Self | None = None) -> Self:
        """Like :meth:`from_table` for the keys of ``table`` that are fields (a table shared with other
        settings, such as the time grid in ``[emulation]``); the other keys are left to the caller."""
        if not isinstance(table, dict):
            raise ConfigError(f"expected a table, got {table!r}", source=source, key=where or cls.TABLE)
        names = {f.name for f in fields(cls)}
        return cls.from_table({k: v for k, v in table.items() if k in names}, source=source, where=where, base=base)


#: The deepest nesting of tables and arrays a config may have (gevsim's own go 4 deep, as in
#: ``light.groups.NAME.waveform``); deeper ones are refused before anything recurses into them.
MAX_NESTING = 32
#: The largest config file read (gevsim's own are a few kB).
MAX_TOML_BYTES = 16 << 20


def read_toml(path: Path, *, what: str) -> dict:
    """Parse a TOML file; a missing, unreadable, non-UTF-8, malformed or too deeply nested file is a
    :class:`ConfigError`."""
    try:
        text = _read_text(Path(path), what)
    except FileNotFoundError:
        raise ConfigError(f"no such {what}", source=str(path)) from None
    except IsADirectoryError:
        raise ConfigError(f"is a folder, not a file (expected the {what})", source=str(path)) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not UTF-8 text: byte {exc.start} is 0x{exc.object[exc.start]:02x} (expected the {what} "
                          "in TOML)", source=str(path)) from None
    except OSError as exc:  # permissions, a device, an I/O error
        raise ConfigError(f"cannot read the {what}: {exc.strerror or exc}", source=str(path)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"malformed TOML: {exc}", source=str(path)) from None
    except RecursionError:
        raise ConfigError(f"malformed TOML: nested more than {MAX_NESTING} levels deep", source=str(path)) from None
    _check_nesting(data, source=str(path))
    return data


def _read_text(path: Path, what: str) -> str:
    """The file's text; a FIFO or device (which could block or never end) and a file over
    :data:`MAX_TOML_BYTES` are refused before they are read."""
    if path.exists() and not path.is_dir() and not path.is_file():
        raise ConfigError(f"not a regular file (expected the {what})", source=str(path))
    with open(path, "rb") as f:
        data = f.read(MAX_TOML_BYTES + 1)
    if len(data) > MAX_TOML_BYTES:
        raise ConfigError(f"larger than {MAX_TOML_BYTES >> 20} MiB (expected the {what})", source=str(path))
    return data.decode("utf-8")


def _check_nesting(data: dict, *, source: str) -> None:
    """Refuse tables and arrays nested deeper than :data:`MAX_NESTING` (walked without recursion)."""
    stack: list[tuple[Any, int]] = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > MAX_NESTING:
            raise ConfigError(f"malformed TOML: nested more than {MAX_NESTING} levels deep", source=source)
        children = value.values() if isinstance(value, dict) else value
        stack.extend((v, depth + 1) for v in children if isinstance(v, (dict, list)))


def load_table(path: str | Path, *, what: str, tables: Sequence[str]) -> tuple[dict, TomlReader]:
    """The prelude of every config loader: parse the TOML file at ``path`` (:func:`read_toml`; ``what``
    names the kind of file in errors) and refuse a top-level key outside ``tables``. Returns the parsed
    tree and a :class:`TomlReader` whose errors name the file."""
    raw = read_toml(Path(path), what=what)
    reader = TomlReader(str(path))
    check_keys(raw, tables, source=reader.source, where="")
    return raw, reader


def resolve_relative(value: Any, base_dir: str | Path) -> Any:
    """A relative ``.toml`` path (a scene manifest or sensor preset named in a config) taken from
    ``base_dir``, the folder of the file that names it, not from the working directory, as an absolute
    path; anything else (a built-in name, an absolute path, not a string) as it is."""
    if isinstance(value, str) and value.endswith(".toml") and not Path(value).is_absolute():
        return str((Path(base_dir) / value).resolve())
    return value


class TomlReader:
    """Typed access to a TOML table with errors that name file and key."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, message: str) -> NoReturn:
        raise ConfigError(message, source=self.source, key=key)

    def number(self, table: dict, key: str, where: str, default: Any = None, *, positive: bool = False,
               minimum: float | None = None, maximum: float | None = None, integer: bool = False) -> Any:
        if key not in table:
            if default is None:
                self.fail(f"{where}.{key}", "missing")
            return default
        value = table[key]
        try:
            if integer:
                low = 1 if positive else None if minimum is None else int(minimum)
                _validate.integer(value, key, low=low, high=None if maximum is None else int(maximum))
            else:
                _validate.real(value, key, low=0.0 if positive else minimum, low_open=positive, high=maximum)
        except FieldError as err:
            self.fail(f"{where}.{key}", str(err))
        return value

    def vector(self, table: dict, key: str, where: str, default: tuple[float, float, float] | None = None, *,
               nonnegative: bool = False) -> tuple[float, float, float]:
        """A 3-vector of finite numbers (a position, direction or RGB triple)."""
        if key not in table:
            if default is None:
                self.fail(f"{where}.{key}", "missing")
            return default
        value = table[key]
        if (
            not isinstance(value, list)
            or len(value) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
        ):
            self.fail(f"{where}.{key}", f"expected 3 finite numbers, got {value!r}")
        if nonnegative and any(v < 0 for v in value):
            self.fail(f"{where}.{key}", f"must not be negative, got {value!r}")
        x, y, z = (float(v) for v in value)
        return x, y, z

    def table(self, data: dict, key: str, where: str = "") -> dict:
        value = data.get(key, {})
        if not isinstance(value, dict):
            self.fail(f"{where}{key}", f"expected a table, got {value!r}")
        return value

    def list(self, data: dict, key: str, where: str = "", default: list | None = None, *,
             of: type | tuple[type, ...] | None = None, item: str = "") -> list:
        """``data[key]`` as a list (``default`` when absent), each item an ``of`` (described as ``item``)
        where given: a string where a list belongs is refused as such, not read as its letters."""
        value = data.get(key, [] if default is None else default)
        if not isinstance(value, list):
            self.fail(f"{where}{key}", f"expected a list{f', each item {item}' if item else ''}, got {value!r}")
        if of is not None:
            for i, x in enumerate(value):
                if not isinstance(x, of) or isinstance(x, bool):
                    self.fail(f"{where}{key}[{i}]", f"expected {item or of}, got {x!r}")
        return value
