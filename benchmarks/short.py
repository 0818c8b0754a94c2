"""Short captures of one object: how much of each is valid, and none wrong (markdown rows).

    python benchmarks/short.py [--seed K] [--count N] [--out DIR]

Labs record 15-50 ms around an event: each capture here is the jump (anywhere in its
0.3 s: take-off, flight, landing, the foot slowing, turning or bouncing at its rest) or
the rail (its start, its run, its stop), 15-50 ms at a random start and seed, with the
simulator's default instrument or a lab's (`simulator.LAB`), one object in view.
Default options, the default backend. Per capture: the truth's span and largest speed,
the share of pairs valid, the valid pairs more than 2 mm from the truth ("wrong": must
be 0), the objects found and the target's choice. Reproducible: the draws follow --seed.
"""

from __future__ import annotations

import numpy as np
from scratch import draws

from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import WRONG_M, truth_at
from fmcw_cl.simulator import LAB, SimulationConfig, jump, rail, simulate_capture

args, out, rng = draws(__doc__, "fmcw-short-", 11, 20)
be = make_processor("auto")
KINDS = {"jump": (jump(0.3), 0.28), "rail": (rail(0.4), 0.38)}
print("| capture | instrument | seed | truth m | largest speed m/s | valid % | wrong | objects | choice |")
print("|---|---|---|---|---|---|---|---|---|")
shares, wrong_all = [], 0
for i in range(args.count):
    kind = str(rng.choice(list(KINDS)))
    traj, latest = KINDS[kind]
    start, duration = float(rng.uniform(0.0, latest)), float(rng.uniform(0.015, 0.05))
    lab = bool(rng.random() < 0.5)
    seed = int(rng.integers(1, 1000))
    path = out / f"short{args.seed}_{i}.h5"
    if not path.exists():
        simulate_capture(path, traj, duration, seed=seed, config=LAB if lab else SimulationConfig(),
                         start_s=start)
    track = process(path, processor=be)
    with Capture(path) as cap:
        truth = cap.truth()
    d, v, _ = truth_at(truth, track.time_s)
    wrong = int(np.sum(track.valid & (np.abs(track.distance_m - d) > WRONG_M)))
    shares.append(float(track.valid.mean()))
    wrong_all += wrong
    print(f"| {kind} {1e3 * start:.0f}+{1e3 * duration:.0f} ms | {'lab' if lab else 'default'} | {seed} | "
          f"{d.min():.3f}-{d.max():.3f} | {np.abs(v).max():.2f} | {100 * track.valid.mean():.1f} | {wrong} | "
          f"{len(track.objects)} | {track.attrs['target_choice']} |", flush=True)
print(f"\ncaptures >= 90 % valid: {sum(s >= 0.9 for s in shares)} of {args.count}; the least "
      f"{100 * min(shares):.1f} %; valid pairs more than 2 mm off: {wrong_all}")
