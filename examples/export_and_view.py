"""Export an emulation file for other tools and draw its events.

``python examples/export_and_view.py [OUT_DIR]`` (default ``out/examples``): uses ``OUT_DIR/office.h5``,
and where that is missing runs ``examples/emulate_scene.py`` first to write it.
"""

import runpy
import sys
from pathlib import Path

from gevsim.evaluation import reconstruct_file
from gevsim.io.exports import export
from gevsim.view import view

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/examples")
run = out / "office.h5"
if not run.exists():  # a fresh folder: emulate the scene first, as examples/emulate_scene.py does
    runpy.run_path(str(Path(__file__).with_name("emulate_scene.py")), run_name="__main__")
print(export(run, out / "office.txt", "text"))  # t x y p, t in seconds
print(export(run, out / "office.npz", "npz"))  # every stream, tonic's fields
view(run, out / "office.gif", window_us=1000)  # event pictures beside the ground truth
recon, truth, tone = reconstruct_file(run, "dct")  # Poisson reconstruction from gradient events
print(f"reconstructed {len(truth)} frames: {recon.mean_metrics()}")
