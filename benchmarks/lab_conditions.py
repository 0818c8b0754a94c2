"""A lab's conditions, one table each (markdown on stdout).

    python benchmarks/lab_conditions.py [--part delay|full-scale|clipping|rest|all] [--out DIR]

- delay: static targets at 0.1, 0.4 and 0.7 m (N = 2048 points at 0.7 m: beyond the
  0.47 m of N = 1000), 50 ms, the lab's instrument
  (`simulator.LAB`), seeds 1-4: the sync delay from the intensity triangle alone and
  refined on the target, against the simulator's hidden delay, with their stated
  uncertainties, and the valid pairs' mean velocity (the bias a delay error leaves on a
  still target) and its stated velocity uncertainty (k = 2, median).
- full-scale: a target at 0.3 m and a wall of 300 codes at 0.45 m, 50 ms, the lab's
  instrument with 3000 codes rms of noise and no gain headroom (noise at full scale),
  seeds 1-12: the refined delay's error against its stated uncertainty.
- clipping: a static target at 0.3 m, 20 ms, -16 dB per sample, 3000 codes rms of noise
  and no headroom (noise peaks at full scale in ~0.7 % of the codes), seeds 1-3: the
  pairs stay valid and precise, the clipped codes counted.
- rest: the 0.3 s jump (`fmcw-cl simulate jump --duration 0.3`) with a laser whose
  thermal tuning lags 4 or 5 us, no calibration given (the track calibrates a chirp on
  the target's own rest), eleven seeds (`REST_ROWS`), six with the lab's instrument.

Default options, the default backend. The distance scale over many G(I) tables is
`benchmarks/distance_scale.py`.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
from scratch import folder

import fmcw_cl
from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import accuracy, valid_errors
from fmcw_cl.options import Options
from fmcw_cl.simulator import LAB, SimulationConfig, simulate_capture, static
from fmcw_cl.stages import faults

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--part", choices=["delay", "full-scale", "clipping", "rest", "all"], default="all")
parser.add_argument("--out", default=None, help="folder for the captures, kept (default: a removed temp dir)")
args = parser.parse_args()
out = folder(args.out, "fmcw-lab-")
be = make_processor("auto")
# (seed, thermal lag us, the lab's instrument) of `fmcw-cl simulate jump --duration 0.3`
REST_ROWS = [(162, 5.0, False), (165, 5.0, False), (166, 5.0, False), (167, 5.0, False), (168, 4.0, False),
             (169, 5.0, True), (171, 5.0, True), (172, 5.0, True), (173, 5.0, True), (2, 5.0, True),
             (4, 5.0, True)]


def delays(path, hidden: dict, options: Options | None = None) -> tuple:
    """The errors of `path`'s delays: intensity, its sigma, refined, its sigma
    (samples); its valid pairs' mean velocity (m/s) and its track."""
    t = process(path, options, processor=be)
    true = float(hidden["sync_delay_samples"])
    a = t.attrs
    return (a["sync_delay_intensity_samples"] - true, a["sync_delay_intensity_uncertainty_samples"],
            a["sync_delay_samples"] - true, a["sync_delay_uncertainty_samples"],
            float(np.mean(t.velocity_mps[t.valid])) if t.valid.any() else float("nan"), t)


def part_delay() -> None:
    print("### Sync delay\n")
    print("| target m | seed | intensity error | its sigma | refined error | its sigma | valid % | "
          "mean v m/s | stated U m/s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for d in (0.1, 0.4, 0.7):
        for seed in range(1, 5):
            path = out / f"delay_{d}_{seed}.h5"
            hidden = simulate_capture(path, static(0.05, d), 0.05, seed=seed, config=LAB)
            ei, si, er, sr, v, t = delays(path, hidden, Options(points=2048 if d > 0.45 else 1000))
            print(f"| {d} | {seed} | {ei:+.2f} | {si:.2f} | {er:+.2f} | {sr:.2f} | "
                  f"{100 * t.valid.mean():.1f} | {v:+.5f} | "
                  f"{np.median(t.velocity_uncertainty_mps[t.valid]):.5f} |", flush=True)
    print()


def part_full_scale() -> None:
    print("### Noise at full scale\n")
    print("| seed | refined error | its sigma | error / sigma | valid % | wrong |")
    print("|---|---|---|---|---|---|")
    cfg = replace(LAB, noise_codes=3000.0, headroom=None, reflectors=((0.45, 300.0),))
    errs, ratios = [], []
    for seed in range(1, 13):
        path = out / f"fullscale_{seed}.h5"
        hidden = simulate_capture(path, static(0.05, 0.3), 0.05, seed=seed, config=cfg)
        _, _, er, sr, _, t = delays(path, hidden)
        with Capture(path) as cap:
            wrong = int(np.sum(valid_errors(t, cap.truth()) > 2e-3))
        errs.append(er)
        ratios.append(er / sr)
        print(f"| {seed} | {er:+.2f} | {sr:.2f} | {er / sr:+.2f} | {100 * t.valid.mean():.1f} | {wrong} |",
              flush=True)
    e, r = np.array(errs), np.array(ratios)
    print(f"\nrefined delay's error: rms {np.sqrt(np.mean(e ** 2)):.2f} samples, largest "
          f"{np.abs(e).max():.2f}; rms over its stated sigma {np.sqrt(np.mean(r ** 2)):.2f}\n")


def part_clipping() -> None:
    print("### Noise peaks at full scale\n")
    print("| seed | codes at full scale % | valid % | dist std mm | dist max mm | flagged clipped |")
    print("|---|---|---|---|---|---|")
    cfg = SimulationConfig(echo_codes=2016.0, snr_db=-16.0, headroom=None)   # 3000 codes rms at 0.3 m
    for seed in range(1, 4):
        path = out / f"clip_{seed}.h5"
        simulate_capture(path, static(0.02, 0.3), 0.02, seed=seed, config=cfg)
        with Capture(path) as cap:
            beat, _ = cap.read(0, cap.info.samples)
            share = float(np.mean(faults.is_clipped(beat, 8192)))
            t = process(path, processor=be)
            acc = accuracy(t, cap.truth())
        print(f"| {seed} | {100 * share:.2f} | {100 * acc['valid_share']:.1f} | "
              f"{1e3 * acc['distance_std_m']:.3f} | {1e3 * acc['distance_max_m']:.3f} | "
              f"{t.attrs['invalid_clipped']} |", flush=True)
    print()


def part_rest() -> None:
    print("### Calibrated on its own rest\n")
    print("| seed | lag us | instrument | rest calibration | valid % | dist p95 mm | dist max mm | "
          "vel p95 m/s |")
    print("|---|---|---|---|---|---|---|---|")
    for seed, lag, lab in REST_ROWS:
        path = out / f"rest_{seed}.h5"
        fmcw_cl.simulate(path, "jump", duration=0.3, seed=seed, thermal_lag_us=lag, lab=lab)
        with Capture(path) as cap:
            t = process(path, processor=be)
            acc = accuracy(t, cap.truth())
        made = t.attrs.get("rest_calibration", "-")
        print(f"| {seed} | {lag:g} | {'lab' if lab else 'default'} | {made} | "
              f"{100 * acc['valid_share']:.2f} | {1e3 * acc['distance_p95_m']:.3f} | "
              f"{1e3 * acc['distance_max_m']:.3f} | {acc['velocity_p95_mps']:.4f} |", flush=True)
    print()


for name, run in (("delay", part_delay), ("full-scale", part_full_scale), ("clipping", part_clipping),
                  ("rest", part_rest)):
    if args.part in (name, "all"):
        run()
