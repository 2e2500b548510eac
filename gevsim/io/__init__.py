"""File formats: HDF5 event files, EVREAL folders, text events, tonic event arrays, OpenEXR images,
frame sequences, atomic writes.

The names below are imported on first use (:mod:`gevsim._lazy`): checking an output folder's
ownership does not import h5py or OpenEXR.
"""

from gevsim._lazy import attach

TYPE_CHECKING = False
if TYPE_CHECKING:
    from gevsim.io.atomic import (
        MANIFEST,
        Staged,
        atomic_dir,
        atomic_path,
        atomic_write_text,
        exclusive,
        remove_stale,
        sweep_stale,
    )
    from gevsim.io.evreal import export_evreal, import_evreal
    from gevsim.io.exr import read_exr, read_exr_layers, write_exr, write_exr_layers
    from gevsim.io.frames import load_evreal_frames, load_frame_folder, load_video
    from gevsim.io.hdf5 import EventReader, EventWriter
    from gevsim.io.text import export_text, import_text
    from gevsim.io.tonic_events import sensor_size as tonic_sensor_size
    from gevsim.io.tonic_events import to_tonic

__getattr__, __dir__ = attach(__name__, {
    **dict.fromkeys(("MANIFEST", "Staged", "atomic_dir", "atomic_path", "atomic_write_text", "exclusive",
                     "remove_stale", "sweep_stale"), "atomic"),
    "export_evreal": "evreal", "import_evreal": "evreal",
    **dict.fromkeys(("read_exr", "read_exr_layers", "write_exr", "write_exr_layers"), "exr"),
    **dict.fromkeys(("load_evreal_frames", "load_frame_folder", "load_video"), "frames"),
    "EventReader": "hdf5", "EventWriter": "hdf5",
    "export_text": "text", "import_text": "text",
    "tonic_sensor_size": "tonic_events:sensor_size", "to_tonic": "tonic_events",
})

__all__ = [
    "EventReader",
    "EventWriter",
    "MANIFEST",
    "Staged",
    "atomic_dir",
    "atomic_path",
    "atomic_write_text",
    "exclusive",
    "export_evreal",
    "export_text",
    "import_evreal",
    "import_text",
    "load_evreal_frames",
    "load_frame_folder",
    "load_video",
    "read_exr",
    "read_exr_layers",
    "remove_stale",
    "sweep_stale",
    "to_tonic",
    "tonic_sensor_size",
    "write_exr",
    "write_exr_layers",
]
