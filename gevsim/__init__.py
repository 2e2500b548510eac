"""gevsim: a physically based event-camera emulator.

Mitsuba 3 renders HDR irradiance of scenes with flickering lamps; a
logarithmic photoreceptor and noise model turns it into pixel voltages that
drive brightness (DVS) and gradient event emulators (Lehtonen et al.).
"""

__version__ = "0.1.0"
