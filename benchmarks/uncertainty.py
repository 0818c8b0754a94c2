"""Per-pair uncertainty against /truth: coverage and sharpness (markdown rows on stdout).

    python benchmarks/uncertainty.py [--seeds 1-6] [--kinds static] [--out DIR]

For each kind of capture, over several seeds: the share of valid pairs whose distance
(of verified velocities whose velocity, of valid accelerations whose acceleration) lies
within its expanded uncertainty (k = 2), and the median uncertainty over the rms error
(the goal: >= 95 % and <= 3).
Then captures with faults the velocity check is for (a sync 60 samples ahead of the
beat, a sample-rate attribute 1 % off, a wall): velocities and accelerations called
valid against their truth. Default options, the default backend.
"""

import argparse
from dataclasses import replace

import h5py
import numpy as np
from scratch import folder

from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import truth_at
from fmcw_cl.simulator import LAB, SimulationConfig, jump, rail, simulate_capture, static

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--seeds", default="1-6", help="seeds a-b (default 1-6)")
parser.add_argument("--kinds", default="", help="only the kinds whose name starts with this (no faults then)")
parser.add_argument("--out", default=None, help="folder for the captures, kept (default: a removed temp dir)")
args = parser.parse_args()
lo, hi = map(int, args.seeds.split("-"))
out = folder(args.out, "fmcw-unc-")
be = make_processor("auto")
DEF = SimulationConfig()
kinds = [("static 0.30 m", static(0.02, 0.30), 0.02, 0.0, DEF),
         ("static 0.30 m, lab", static(0.02, 0.30), 0.02, 0.0, LAB),
         ("rail 50-100 ms", rail(0.4), 0.05, 0.05, DEF),
         ("rail 50-100 ms, lab", rail(0.4), 0.05, 0.05, LAB),
         ("jump 60-110 ms", jump(0.3), 0.05, 0.06, DEF),
         ("jump 180-230 ms (landing), lab + speckle", jump(0.3), 0.05, 0.18, replace(LAB, speckle_s=3e-3)),
         ("jump 60-110 ms, lab + wall 0.42:1500 + speckle", jump(0.3), 0.05, 0.06,
          replace(LAB, reflectors=((0.42, 1500.0),), speckle_s=3e-3))]


def errors(track, truth, fs_scale=1.0):
    d, v, a = truth_at(truth, track.time_s * fs_scale)
    return (np.abs(track.distance_m - d), np.abs(track.velocity_mps - v), np.abs(track.acceleration_mps2 - a))


print("| capture | seeds | pairs | valid % | velocity verified % | distance within U % | median U / rms "
      "error | velocity within U % | median U / rms error | acceleration within U % | median U / rms error | "
      "captures with distances outside U |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for name, traj, dur, start, cfg in (k for k in kinds if k[0].startswith(args.kinds)):
    ed, ud, ev, uv, ea, ua, n, nv, nvv, outside = [], [], [], [], [], [], 0, 0, 0, 0
    for seed in range(lo, hi + 1):
        path = out / "c.h5"
        path.unlink(missing_ok=True)
        simulate_capture(path, traj, dur, seed=seed, config=cfg, start_s=start)
        t = process(path, processor=be)
        with Capture(path) as cap:
            e_d, e_v, e_a = errors(t, cap.truth())
        ed.append(e_d[t.valid]), ud.append(t.distance_uncertainty_m[t.valid])
        ev.append(e_v[t.velocity_valid]), uv.append(t.velocity_uncertainty_mps[t.velocity_valid])
        ea.append(e_a[t.acceleration_valid]), ua.append(t.acceleration_uncertainty_mps2[t.acceleration_valid])
        n, nv, nvv = n + t.pairs, nv + int(t.valid.sum()), nvv + int(t.velocity_valid.sum())
        if t.valid.any():
            outside += int(np.mean(e_d[t.valid] <= t.distance_uncertainty_m[t.valid]) < 0.95)
    ed, ud, ev, uv, ea, ua = map(np.concatenate, (ed, ud, ev, uv, ea, ua))
    print(f"| {name} | {lo}-{hi} | {n} | {100 * nv / n:.1f} | {100 * nvv / max(nv, 1):.1f} | "
          f"{100 * np.mean(ed <= ud):.1f} | {np.median(ud) / np.sqrt(np.mean(ed**2)):.2f} | "
          f"{100 * np.mean(ev <= uv):.1f} | {np.median(uv) / np.sqrt(np.mean(ev**2)):.2f} | "
          f"{100 * np.mean(ea <= ua):.1f} | {np.median(ua) / np.sqrt(np.mean(ea**2)):.2f} | "
          f"{outside} of {hi - lo + 1} |", flush=True)

if args.kinds:
    raise SystemExit(0)
faults = [("jump 60-110 ms, sync 60 samples ahead of the beat", jump(0.3), 0.05, 0.06,
           replace(DEF, sync_delay_samples=-60.0), 1.0),
          ("rail 50-100 ms, sync 60 samples ahead of the beat", rail(0.4), 0.05, 0.05,
           replace(DEF, sync_delay_samples=-60.0), 1.0),
          ("rail 50-100 ms, sample-rate attribute 1 % high", rail(0.4), 0.05, 0.05, DEF, 1.01),
          ("jump 60-110 ms, sample-rate attribute 1 % high", jump(0.3), 0.05, 0.06, DEF, 1.01),
          ("jump 0.3 s, 0 dB, wall 0.42:800 + speckle (the tutorial's)", jump(0.3), 0.3, 0.0,
           replace(DEF, snr_db=0.0, reflectors=((0.42, 800.0),), speckle_s=3e-3), 1.0)]
print()
print("| capture | seed | valid % | velocity verified % | max velocity error, all valid m/s | ... verified "
      "m/s | verified within U % | verified beyond 3 U | acceleration valid % | max acceleration error "
      "m/s^2 | accelerations beyond 3 U |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for name, traj, dur, start, cfg, fs in faults:
    for seed in (lo, lo + 1):
        path = out / "f.h5"
        path.unlink(missing_ok=True)
        simulate_capture(path, traj, dur, seed=seed, config=cfg, start_s=start)
        if fs != 1.0:
            with h5py.File(path, "r+") as f:
                f["adc"].attrs["sample_rate_hz"] *= fs
        t = process(path, processor=be)
        with Capture(path) as cap:
            e_d, e_v, e_a = errors(t, cap.truth(), fs)
        vv, av = t.velocity_valid, t.acceleration_valid
        u = t.velocity_uncertainty_mps[vv]

        def mx(x):
            return float(np.max(x)) if x.size else float("nan")

        verified = 100 * vv.sum() / max(t.valid.sum(), 1)
        print(f"| {name} | {seed} | {100 * t.valid.mean():.1f} | {verified:.1f} | "
              f"{mx(e_v[t.valid]):.4f} | {mx(e_v[vv]):.4f} | {100 * np.mean(e_v[vv] <= u):.1f} | "
              f"{int(np.sum(e_v[vv] > 3 * u))} | {100 * av.mean():.1f} | {mx(e_a[av]):.1f} | "
              f"{int(np.sum(e_a[av] > 3 * t.acceleration_uncertainty_mps2[av]))} |", flush=True)
