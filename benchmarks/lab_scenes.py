"""Lab conditions: every valid pair of 26 captures against /truth (markdown rows on stdout).

    python benchmarks/lab_scenes.py [--out DIR]

The project's simulator made as unkind as a lab: an intensity triangle of +-150 codes
under 600 codes rms of noise, a G(I) table with 20 MHz scatter, 50 ms captures on several
seeds (statics, the jump's take-off and landing, the rail's start), a stronger wall with
speckle, a window in front, a wall 12 dB over a target at rest, a far stronger wall in
the take-off's path, a noise of 3000 codes (the simulator then scales its gain
down so that noise never clips: noise peaks at full scale it cannot make yet), and one
0.3 s jump with a wall. Default options, the default backend. "wrong" counts valid pairs more than
2 mm from the truth: it must be 0.
"""

import argparse
from dataclasses import replace

import numpy as np
from scratch import folder

from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import covered, invalid_reasons, objects_cell, valid_errors
from fmcw_cl.simulator import LAB, jump, rail, simulate_capture, static

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=None, help="folder for the captures, kept (default: a removed temp dir)")
out = folder(parser.parse_args().out, "fmcw-lab-")
be = make_processor("auto")
scenes = []
for s in (1, 2, 3):
    scenes += [("static 0.30 m, lab", static(0.05, 0.30), 0.05, 0.0, s, LAB),
               ("static 0.40 m, lab", static(0.05, 0.40), 0.05, 0.0, s, LAB),
               ("jump 60-110 ms, lab", jump(0.3), 0.05, 0.06, s, LAB),
               ("jump 60-110 ms, lab + wall 0.42:1500 + speckle", jump(0.3), 0.05, 0.06, s,
                replace(LAB, reflectors=((0.42, 1500.0),), speckle_s=3e-3)),
               ("jump 180-230 ms (landing), lab + speckle", jump(0.3), 0.05, 0.18, s,
                replace(LAB, speckle_s=3e-3))]
for s in (1, 2):
    scenes += [("jump 60-110 ms, lab + window 0.05:800", jump(0.3, ground_m=0.09), 0.05, 0.06, s,
                replace(LAB, reflectors=((0.05, 800.0),))),
               ("static 0.25 m, noise 3000 codes (gain keeps it off full scale)", static(0.05, 0.25), 0.05,
                0.0, s, replace(LAB, noise_codes=3000.0)),
               ("rail 50-100 ms, lab", rail(0.4), 0.05, 0.05, s, LAB),
               ("static 0.40 m, lab + wall 0.25:1500 (12 dB stronger)", static(0.05, 0.40), 0.05, 0.0, s,
                replace(LAB, reflectors=((0.25, 1500.0),))),
               ("jump 60-110 ms, lab + wall 0.20:3000 in its path", jump(0.3), 0.05, 0.06, s,
                replace(LAB, reflectors=((0.20, 3000.0),)))]
scenes += [("jump 0.3 s, lab + wall 0.42:800 + speckle", jump(0.3), 0.3, 0.0, 4,
            replace(LAB, reflectors=((0.42, 800.0),), speckle_s=3e-3))]
print("| scene | seed | valid % | wrong | max error mm | within U % | objects (wrong) "
      "| invalid pairs by reason |")
print("|---|---|---|---|---|---|---|---|")
worst = 0
for i, (name, traj, dur, start, seed, cfg) in enumerate(scenes):
    path = out / f"c{i}.h5"
    simulate_capture(path, traj, dur, seed=seed, config=cfg, start_s=start)
    try:
        t = process(path, processor=be)
    except Exception as exc:  # noqa: BLE001 - a scene that cannot be converted is a row too
        print(f"| {name} | {seed} | error: {exc} | | | | | |")
        continue
    with Capture(path) as cap:
        err = valid_errors(t, cap.truth())
        scene = objects_cell(t, cap.truth_objects())
    bad = int(np.sum(err > 2e-3))
    within = covered(t, err)
    worst += bad
    why = invalid_reasons(t)
    print(f"| {name} | {seed} | {100 * t.valid.mean():.1f} | {bad} | "
          f"{np.max(err) * 1e3 if err.size else float('nan'):.2f} | {within} | {scene} | {why} |", flush=True)
print("valid pairs > 2 mm off, all scenes:", worst)
