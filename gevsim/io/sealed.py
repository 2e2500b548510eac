"""Sealed reads (issue 36, item 2): every dataset gevsim reads from an HDF5 file is stored in that file.

HDF5 lets a file hand its reader bytes that live elsewhere: a dataset's raw data in *external storage*
(any file named by path, ``h5py.Group.create_dataset(external=...)``), an *external link* to an object
of another HDF5 file, a *virtual dataset* mapping other files' datasets, and *soft links* by path (which
may dangle, or lead through an external link). A crafted event file could so make ``gevsim export``
copy another file's bytes into its output. gevsim writes none of these (only hard links: the root
``ms_to_idx`` is one), so :func:`check_sealed` refuses a file holding any of them anywhere, or a soft
link that does not resolve inside the file, with one :class:`~gevsim.errors.ConfigError` naming the
file and the dataset or link, when the file is opened and before a byte of any dataset is read.

The walk visits every link of the file once (HDF5's ``H5Lvisit``: hard links only are followed, each
group once, so cycles end) and reads each dataset's creation properties, not its data. A file with
more than :data:`MAX_LINKS` links is not one gevsim wrote and is refused rather than walked for long.
"""

from __future__ import annotations

import h5py
from h5py import h5d

from gevsim.errors import ConfigError, clipped

__all__ = ["MAX_LINKS", "check_sealed"]

#: Most links a file may hold: a gevsim file holds a few dozen (walking 10,000 takes ~0.6 s).
MAX_LINKS = 10_000
#: What h5py raises for a structure it cannot read.
_H5_ERRORS = (OSError, RuntimeError, KeyError, TypeError, ValueError)


def _refuse(source: str, name: str, why: str) -> ConfigError:
    return ConfigError(f"{why}: gevsim reads only data stored in the file itself", source=source,
                       key=clipped("/" + name.lstrip("/")))


def _dataset_layout(obj: object) -> str | None:
    """Why a dataset's data are not in its file (external raw storage, virtual), or None."""
    if not isinstance(obj, h5py.Dataset):
        return None
    dcpl = obj.id.get_create_plist()
    if dcpl.get_layout() == h5d.VIRTUAL:
        return "is a virtual dataset (its data are other files' datasets)"
    count = dcpl.get_external_count()
    if count:
        target = dcpl.get_external(0)[0]
        shown = target.decode(errors="replace") if isinstance(target, bytes) else str(target)
        return f"is stored outside the file (external raw storage in {count} file(s), e.g. {clipped(shown, 200)!r})"
    return None


def check_sealed(file: h5py.File, *, source: str) -> None:
    """Raise :class:`ConfigError` unless every dataset reachable in ``file`` is stored in it (see the
    module's notes); reads link and dataset-creation metadata only."""
    links: list[tuple[str, object]] = []

    def visit(name: str, link: object) -> bool | None:
        links.append((name, link))
        return True if len(links) > MAX_LINKS else None  # a non-None return ends the walk

    try:
        file.visititems_links(visit)
    except _H5_ERRORS as exc:  # an unreadable structure (damaged, an unknown link class) is bad input
        raise ConfigError(f"cannot list the file's objects, the file is damaged ({clipped(str(exc))})",
                          source=source) from None
    if len(links) > MAX_LINKS:
        raise ConfigError(f"holds more than {MAX_LINKS} HDF5 objects: not a file written by gevsim", source=source)
    # Links to other files first: no soft link is resolved (which could follow one) before all are refused.
    for name, link in links:
        if isinstance(link, h5py.ExternalLink):
            raise _refuse(source, name, f"is an external link to {clipped(link.filename, 200)!r}:{clipped(link.path)}")
        if not isinstance(link, h5py.HardLink | h5py.SoftLink):
            raise _refuse(source, name, f"is a link of unknown kind ({type(link).__name__})")
    for name, link in links:
        try:
            obj = file.get(name)
            why = _dataset_layout(obj) if obj is not None else (
                f"is a soft link to {clipped(link.path)!r}, which does not exist in the file"
                if isinstance(link, h5py.SoftLink) else "cannot be opened")
        except _H5_ERRORS as exc:  # HDF5 refuses to open it: damaged, or a loop of soft links
            why = f"cannot be opened ({clipped(str(exc))})"
        if why:
            raise _refuse(source, name, why)
