"""Cost of the light-dependent leak in the DVS kernel (issue 23): the same 346x260 x 500-step chunk with
leak_light_hz_per_a = 0 and 3e8, alternately, 5 times; medians and their ratio. Run:
NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/leak_cost.py"""
import time

import numpy as np

from gevsim.events import BrightnessEmulator
from gevsim.pixel.params import EventParams
shape=(260,346); T=500
rng=np.random.default_rng(0)
v=(np.log(1e-12)+np.cumsum(0.01*rng.standard_normal((T,)+shape),axis=0)).astype(np.float32)
t=2e-5*np.arange(1,T+1)
res={0:[],1:[]}
for rep in range(5):
    for light in (0,1):
        p=EventParams(threshold_on_ln=0.2,threshold_off_ln=0.2,leak_rate_hz=0.05,leak_light_hz_per_a=3e8 if light else 0.0)
        em=BrightnessEmulator(shape,p,rng=np.random.default_rng(1))
        em.process(v[:2],t[:2])
        a=time.perf_counter(); ev=em.process(v[2:],t[2:]); res[light].append(time.perf_counter()-a)
print("median s without light leak", np.median(res[0]), "with", np.median(res[1]), "ratio", np.median(res[1])/np.median(res[0]), len(ev))
