"""Weak echoes: single half-sweeps against K integrated (markdown rows on stdout).

    python benchmarks/weak.py [--seeds 1-3] [--out DIR]

The captures of `tests/test_integrate.py`, on several seeds: a static target at 0.3 m
at -16 dB per sample (20 ms); a take-off from a ground at 0.25 m at -16 dB (36 ms from
30 ms: standing, then to 5 m/s); the whole 0.3 s jump at -18 dB. Each converted with
single half-sweeps (`--integrate 1`) and with K chosen from the measured SNR per chunk
(the default), on the default backend, the whole jump on numpy too (its chunks of 58 ms
choose K apart; a device's one chunk holds the capture: `docs/pipeline.md` 7b). Errors
of the valid pairs against /truth.
"""

from __future__ import annotations

import argparse

import numpy as np
from scratch import folder, seeds

from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import accuracy
from fmcw_cl.options import Options
from fmcw_cl.simulator import SimulationConfig, jump, simulate_capture, static

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--seeds", default="1-3", help="seeds, as A-B (default 1-3)")
parser.add_argument("--out", default=None, help="folder for the captures, kept (default: a removed temp dir)")
args = parser.parse_args()
out = folder(args.out, "fmcw-weak-")
SCENES = {  # name: (trajectory, duration s, start s, SNR dB per sample, backends)
    "static 0.3 m, -16 dB": (static(0.02, 0.3), 0.02, 0.0, -16.0, ("auto",)),
    "take-off, -16 dB": (jump(0.3, ground_m=0.25), 0.036, 0.03, -16.0, ("auto",)),
    "jump 0.3 s, -18 dB": (jump(0.3), 0.3, 0.0, -18.0, ("auto", "numpy")),
}
print("| capture | backend | seed | single valid % | valid % | K | dist std mm | dist p95 mm | "
      "dist max mm | vel p95 m/s |")
print("|---|---|---|---|---|---|---|---|---|---|")
processors: dict = {}
for name, (traj, duration, start, snr, backends) in SCENES.items():
    for backend, seed in ((b, s) for b in backends for s in seeds(args.seeds)):
        if backend not in processors:
            processors[backend] = make_processor(backend)
        be = processors[backend]
        path = out / f"{name.split(',')[0].replace(' ', '_')}-{seed}.h5"
        if not path.exists():
            simulate_capture(path, traj, duration, seed=seed, config=SimulationConfig(snr_db=snr),
                             start_s=start)
        single = process(path, Options(integrate=1), be)
        t = process(path, Options(), be)
        with Capture(path) as cap:
            a = accuracy(t, cap.truth())
        k = t.integrated[t.valid] if t.integrated is not None else np.ones(1, int)
        ks = f"{k.min()}-{k.max()}" if k.min() != k.max() else f"{k.max()}"
        print(f"| {name} | {'OpenCL' if backend == 'auto' else backend} | {seed} | "
              f"{100 * single.valid.mean():.1f} | {100 * a['valid_share']:.1f} | {ks} | "
              f"{1e3 * a['distance_std_m']:.3f} | {1e3 * a['distance_p95_m']:.3f} | "
              f"{1e3 * a['distance_max_m']:.3f} | {a['velocity_p95_mps']:.4f} |", flush=True)
