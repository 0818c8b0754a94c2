"""Host work per second of capture: the converting thread's CPU time, best of 5 warm
conversions (markdown rows on stdout).

    python benchmarks/host.py [--backend opencl] [CAPTURE ...]

On PoCL a wait for the device sleeps, so this is the host's own work, the figure that
bounds a GPU's end to end. Without captures: a 1 s rail, the 0.3 s jump and a 0.5 s
static target of the simulator's defaults (seeds 1-3), and two with a lab's instrument
(`simulator.LAB`: a weak intensity triangle under noise, a 20 MHz table): 0.1 s of the jump's
take-off past a wall of 300 codes with speckle, and a 0.2 s static target at -15 dB per
sample, which the tracker integrates; written in a temporary folder. To
compare two versions, install one apart (pip install --target DIR) and run this script
with PYTHONPATH=DIR, alternately with the other, in one session.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from scratch import folder

import fmcw_cl
from fmcw_cl.backend import make_processor
from fmcw_cl.engine import process
from fmcw_cl.options import Options
from fmcw_cl.simulator import jump, rail, simulate_captures, static


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("captures", nargs="*", type=Path)
    ap.add_argument("--backend", default="opencl")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    captures = args.captures
    if not captures:
        tmp = folder(None, "fmcw-host-")
        scenes = (("rail", rail, 1.0), ("jump", jump, 0.3), ("static", static, 0.5))
        captures = simulate_captures([{"path": tmp / f"{name}.h5", "trajectory": scene(seconds),
                                       "duration_s": seconds, "seed": seed}
                                      for seed, (name, scene, seconds) in enumerate(scenes, 1)])
        captures += [tmp / "lab_jump.h5", tmp / "lab_weak_static.h5"]
        fmcw_cl.simulate(captures[-2], "jump", duration=0.1, start=0.05, seed=7, lab=True,
                         reflectors=((0.25, 300.0),), speckle_ms=2.0)
        fmcw_cl.simulate(captures[-1], "static", duration=0.2, seed=5, snr_db=-15, lab=True)
    be = make_processor(args.backend)
    print("| capture | device | host CPU ms per s of capture |\n|---|---|---|")
    for path in captures:
        process(path, Options(), be)                 # warm: programs built, caches filled
        best = float("inf")
        for _ in range(args.repeat):
            t = time.thread_time()
            track = process(path, Options(), be)
            best = min(best, time.thread_time() - t)
        per_s = 1e3 * best / track.attrs["capture_duration_s"]
        print(f"| {path.name} | {track.attrs['device']} | {per_s:.0f} |")


if __name__ == "__main__":
    main()
