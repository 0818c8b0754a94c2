"""Random lab scenes hunted for wrong valid pairs (one line each on stdout).

    python benchmarks/hunt.py [--seed K] [--count N] [--only I ...] [--out DIR]

Each capture is 50 ms of a static target, the jump's take-off or landing, or the rail's
start, with the lab's instrument (`simulator.LAB`), 0-2 static walls (0.05-0.45 m,
150-3000 codes), speckle on half of them and noise at full scale (3000 codes, no
headroom) on a third, each on its own seed. Default options, the default backend.
"wrong" counts the valid pairs of every object more than 2 mm from the truth it follows
(`evaluate.object_scores`; the walls are objects of /truth too); the lines that have any
end in "<<<<". "off the target" counts `/track`'s valid pairs more than 2 mm from the
target's truth: a wall taken for a target never detected (`docs/pipeline.md` 6c) is
right on the wall and off the target. Reproducible: the draws follow --seed, and
`--only 7 24` converts those captures of the draw alone (kept with `--out`).
"""

from dataclasses import replace

import numpy as np
from scratch import draws

from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import object_scores, valid_errors
from fmcw_cl.simulator import LAB, jump, rail, simulate_capture, static

args, out, rng = draws(__doc__, "fmcw-hunt-", 1, 40,
                       ("--only", dict(type=int, nargs="*", help="convert these captures of the draw alone")))
be = make_processor("auto")
total = total_off = 0
for i in range(args.count):
    kind = rng.choice(["static", "jump_up", "jump_land", "rail"])
    walls = tuple((float(rng.uniform(0.05, 0.45)), float(rng.choice([150, 400, 800, 1500, 3000])))
                  for _ in range(rng.integers(0, 3)))
    cfg = replace(LAB, reflectors=walls, speckle_s=3e-3 if rng.random() < 0.5 else 0.0)
    if rng.random() < 0.3:
        cfg = replace(cfg, noise_codes=3000.0, headroom=None)
    seed = int(rng.integers(1, 1000))
    traj, start = {"jump_up": (jump(0.3), 0.06), "jump_land": (jump(0.3), 0.18),
                   "rail": (rail(0.4), 0.05)}.get(kind, (None, 0.0))
    if kind == "static":
        traj = static(0.05, float(rng.uniform(0.05, 0.45)))
    if args.only and i not in args.only:
        continue
    path = out / f"h{args.seed}_{i}.h5"
    simulate_capture(path, traj, 0.05, seed=seed, config=cfg, start_s=start)
    t = process(path, processor=be)
    with Capture(path) as cap:
        err = valid_errors(t, cap.truth())
        bad = sum(s["wrong"] for s in object_scores(t, cap.truth_objects()))
    off = int(np.sum(err > 2e-3))
    total += bad
    total_off += off
    print(f"{i} {kind} walls={[(round(d, 3), a) for d, a in walls]} speckle={cfg.speckle_s > 0} "
          f"full-scale={cfg.noise_codes > 1000} seed={seed}: valid {100 * t.valid.mean():.1f} % wrong {bad} "
          f"off the target {off} (max {err.max() * 1e3 if err.size else float('nan'):.2f} mm) | "
          f"{t.attrs['target_choice']}"
          f"{'  <<<<' if bad else ''}", flush=True)
print("valid pairs > 2 mm off their object's truth, all captures:", total)
print("valid pairs of /track > 2 mm off the target's truth, all captures:", total_off)
