"""File formats: OpenEXR images, atomic writes (HDF5 and EVREAL come later)."""

from gevsim.io.atomic import atomic_path, atomic_write_text
from gevsim.io.exr import read_exr, write_exr

__all__ = ["atomic_path", "atomic_write_text", "read_exr", "write_exr"]
