"""The sync delay on short captures against its stated uncertainty (markdown rows on stdout).

    python benchmarks/delay.py [--seed K] [--count N] [--lab-share 0.5] [--out DIR]

Labs record short captures around an event: each capture here is 15-50 ms of the jump's
take-off or landing, or of the rail's start, at a random start and seed, with the
simulator's default instrument or a lab's (`simulator.LAB`: a weak intensity triangle
under noise). The plan's delay (`plan.make_plan`, numpy stages) is compared with the
simulator's hidden delay: "covered" where the error is within 3 stated sigmas + 0.3
samples; the velocity bias the error leaves (the plan's m/s per sample) against 3x its
stated velocity uncertainty + 1 mm/s. Reproducible: the draws follow --seed.
"""

from __future__ import annotations

from dataclasses import replace

from scratch import draws

from fmcw_cl.capture import Capture
from fmcw_cl.options import Options
from fmcw_cl.plan import make_plan
from fmcw_cl.processor import NumpyProcessor
from fmcw_cl.refine import disagreement
from fmcw_cl.simulator import LAB, SimulationConfig, jump, rail, simulate_capture

args, out, rng = draws(__doc__, "fmcw-delay-", 1, 10, ("--lab-share", {
    "type": float, "default": 0.5, "help": "share of captures with a lab's instrument"}))
SPANS = {"take-off": (jump(0.3), 0.045, 0.09), "landing": (jump(0.3), 0.17, 0.22),
         "rail": (rail(0.4), 0.04, 0.08)}
print("| capture | instrument | seed | ms | true | stated | error | sigmas | covered | velocity bias mm/s | "
      "stated mm/s | covered | intensity | its error | disagreement (sigmas) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
covered = within = 0
for i in range(args.count):
    kind = str(rng.choice(list(SPANS)))
    traj, lo, hi = SPANS[kind]
    start, duration = float(rng.uniform(lo, hi)), float(rng.uniform(0.015, 0.05))
    lab = bool(rng.random() < args.lab_share)
    seed = int(rng.integers(1, 1000))
    cfg = LAB if lab else SimulationConfig()
    path = out / f"d{args.seed}_{i}.h5"
    hidden = simulate_capture(path, traj, duration, seed=seed, config=replace(cfg), start_s=start)
    true = float(hidden["sync_delay_samples"])
    with Capture(path) as cap:
        plan = make_plan(cap, Options(), processor=NumpyProcessor())
        # the velocity bias a delay error leaves: the plan's own sensitivity (m/s per sample)
        per_sample = plan.lag_sigma_mps / plan.lag_sigma_samples if plan.lag_refined else float("nan")
    err = plan.lag - true
    sigma = plan.lag_sigma_samples if plan.lag_refined else float("nan")
    ok = bool(abs(err) <= 3 * sigma + 0.3)
    bias = abs(err) * per_sample * 1e3
    vel_ok = bool(bias <= 3 * plan.lag_sigma_mps * 1e3 + 1.0)
    covered += ok
    within += vel_ok
    print(f"| {kind} {1e3 * start:.0f} ms | {'lab' if lab else 'default'} | {seed} | {1e3 * duration:.0f} | "
          f"{true:+.2f} | {plan.lag:+.2f} +-{sigma:.2f} | {err:+.2f} | {abs(err) / sigma:.1f} | "
          f"{'yes' if ok else 'NO'} | {bias:.2f} | {1e3 * plan.lag_sigma_mps:.2f} | "
          f"{'yes' if vel_ok else 'NO'} | {plan.lag_intensity:+.2f} +-{plan.lag_intensity_sigma:.2f} | "
          f"{plan.lag_intensity - true:+.2f} | {disagreement(plan):.1f} |", flush=True)
print(f"\ndelays within 3 sigma + 0.3 samples: {covered} of {args.count}; velocity bias within 3x its "
      f"stated uncertainty + 1 mm/s: {within} of {args.count}")
