"""Short captures of one object: how much of each is valid, and none wrong (markdown rows).

    python benchmarks/short.py [--seed K] [--count N] [--wall] [--out DIR]

Labs record 15-50 ms around an event: each capture here is the jump (anywhere in its
0.3 s: take-off, flight, landing, the foot slowing, turning or bouncing at its rest) or
the rail (its start, its run, its stop), 15-50 ms at a random start and seed, with the
simulator's default instrument or a lab's (`simulator.LAB`), one object in view.
Default options, the default backend. Per capture: the truth's span and largest speed,
the share of the target's pairs valid on it, the valid pairs of any object more than 2
mm from the truth it follows ("wrong": must be 0), the objects found and the target's
choice. Reproducible: the draws follow --seed. With --wall, a still wall beyond the
object too (0.36-0.47 m beyond the jump, 0.43-0.47 m beyond the rail; 150-800 codes,
which the whole band's tracker may follow).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scratch import draws

from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import WRONG_M, object_scores, truth_at
from fmcw_cl.simulator import LAB, SimulationConfig, jump, rail, simulate_capture

args, out, rng = draws(__doc__, "fmcw-short-", 11, 20,
                       ("--wall", {"action": "store_true", "help": "a still wall beyond the object"}))
be = make_processor("auto")
KINDS = {"jump": (jump(0.3), 0.28), "rail": (rail(0.4), 0.38)}
WALLS = {"jump": (0.36, 0.47), "rail": (0.43, 0.47)}     # m: beyond the object's span
HEAD = ["capture", "instrument", "seed"] + ["wall m:codes"] * args.wall + [
    "truth m", "largest speed m/s", "valid %", "wrong", "objects", "choice"]
print("| " + " | ".join(HEAD) + " |\n|" + "---|" * len(HEAD))
shares, wrong_all = [], 0
for i in range(args.count):
    kind = str(rng.choice(list(KINDS)))
    traj, latest = KINDS[kind]
    start, duration = float(rng.uniform(0.0, latest)), float(rng.uniform(0.015, 0.05))
    lab = bool(rng.random() < 0.5)
    seed = int(rng.integers(1, 1000))
    config = LAB if lab else SimulationConfig()
    wall = ""
    if args.wall:
        at, codes = float(rng.uniform(*WALLS[kind])), float(rng.uniform(150.0, 800.0))
        config, wall = replace(config, reflectors=((at, codes),)), f" {at:.3f}:{codes:.0f} |"
    path = out / f"short{args.seed}{'w' if args.wall else ''}_{i}.h5"
    if not path.exists():
        simulate_capture(path, traj, duration, seed=seed, config=config, start_s=start)
    track = process(path, processor=be)
    with Capture(path) as cap:
        truth, truths = cap.truth(), cap.truth_objects()
    d, v, _ = truth_at(truth, track.time_s)
    # a wall's pairs are its own object's, not the target's: the target holds the object's
    wrong = sum(s["wrong"] for s in object_scores(track, truths))
    held = track.valid & (np.abs(track.distance_m - d) <= WRONG_M)
    shares.append(float(held.mean()))
    wrong_all += wrong
    print(f"| {kind} {1e3 * start:.0f}+{1e3 * duration:.0f} ms | {'lab' if lab else 'default'} | {seed} |"
          f"{wall} {d.min():.3f}-{d.max():.3f} | {np.abs(v).max():.2f} | {100 * held.mean():.1f} | {wrong} | "
          f"{len(track.objects)} | {track.attrs['target_choice']} |", flush=True)
print(f"\ncaptures >= 90 % valid: {sum(s >= 0.9 for s in shares)} of {args.count}; the least "
      f"{100 * min(shares):.1f} %; valid pairs more than 2 mm off: {wrong_all}")
