"""The displacement from the beat's phase against the truth (markdown rows on stdout).

    python benchmarks/phase.py [--seeds 1-3] [--out DIR] [--scene NAME ...]

Scenes of the issue "Nanometres": a static target at 0.4 m (50 ms), at the default
SNR and at a lab's (`--lab`); a creep of 1 mm/s (200 ms), both; the 7 m/s jump
(300 ms), both; a static target and the jump under speckle decorrelating in 3 ms;
vibrations at 0.3 m (100 ms): 5 um at 200 Hz, 1 um at 1 kHz, 2 mm at 50 Hz, 50 um
at 1 kHz (also with `--lab`), 10 um at 1 kHz, 100 um at 700 Hz. Default options, the
default backend. Per scene and seed: the distance's valid share, the displacement's
valid share and stretches, its error against the truth (from the displacement's zero):
rms and largest, the standard deviation of a static target's displacement, a creep's
slope error, the share of valid pairs within their expanded uncertainty (k = 2), and
the pairs whose displacement leaves the peaks' distance by more than their joint
uncertainty.
"""

import argparse
import time

import numpy as np
from scipy.interpolate import CubicSpline
from scratch import folder, seeds

import fmcw_cl
from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.displacement import ZERO_PAIRS
from fmcw_cl.engine import process

SCENES = {
    "static 0.4 m": ("static", {"distance": 0.4}),
    "static 0.4 m, lab": ("static", {"distance": 0.4, "lab": True}),
    "creep 1 mm/s": ("creep", {}),
    "creep 1 mm/s, lab": ("creep", {"lab": True}),
    "jump": ("jump", {}),
    "jump, lab": ("jump", {"lab": True}),
    "static 0.3 m, speckle 3 ms": ("static", {"speckle_ms": 3.0}),
    "jump, speckle 3 ms, 0 dB": ("jump", {"speckle_ms": 3.0, "snr_db": 0.0}),
    "5 um at 200 Hz": ("vibration", {"amplitude_um": 5, "frequency_hz": 200}),
    "1 um at 1 kHz": ("vibration", {"amplitude_um": 1, "frequency_hz": 1000}),
    "2 mm at 50 Hz": ("vibration", {"amplitude_um": 2000, "frequency_hz": 50}),
    "50 um at 1 kHz": ("vibration", {}),
    "50 um at 1 kHz, lab": ("vibration", {"lab": True}),
    "10 um at 1 kHz": ("vibration", {"amplitude_um": 10, "frequency_hz": 1000}),
    "100 um at 700 Hz": ("vibration", {"amplitude_um": 100, "frequency_hz": 700}),
}


def row(track, truth, scenario: str) -> str:
    ok = track.displacement_valid
    cells = [f"{100 * track.valid.mean():.1f}", f"{100 * ok.mean():.1f}",
             str(track.attrs.get("displacement_stretches", 0))]
    if not ok.any():
        return " | ".join(cells + ["-"] * 6)
    r = CubicSpline(truth.time_s, truth.distance_m)(track.time_s)
    zero = np.flatnonzero(track.displacement_stretch == 0)[:ZERO_PAIRS]    # the displacement's zero
    first = zero[0]
    err = (track.displacement_m - (r - np.mean(r[zero])))[ok]
    x = track.displacement_m[ok]
    slope, true_slope = (np.polyfit(track.time_s[ok], y, 1)[0] for y in (x, r[ok]))
    moved = (track.distance_m - np.mean(track.distance_m[zero]))[ok]
    u_d = track.distance_uncertainty_m
    joint = (track.displacement_uncertainty_m + u_d + u_d[first])[ok]
    cells += [f"{1e9 * np.sqrt(np.mean(err ** 2)):.1f}", f"{1e9 * np.max(np.abs(err)):.1f}",
              f"{1e9 * np.std(x):.1f}" if scenario == "static" else "-",
              f"{100 * (slope / true_slope - 1):+.3f}" if scenario == "creep" else "-",
              f"{100 * np.mean(np.abs(err) <= track.displacement_uncertainty_m[ok]):.1f}",
              str(int(np.sum(np.abs(moved - x) > joint)))]
    return " | ".join(cells)


parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--seeds", default="1-3", help="seeds, as A-B (default 1-3)")
parser.add_argument("--out", default=None, help="folder for the captures, kept (default: a removed temp dir)")
parser.add_argument("--scene", action="append", help="only these scenes (names of SCENES)")
args = parser.parse_args()
out = folder(args.out, "fmcw-phase-")
be = make_processor("auto")
print("| scene | seed | valid % | displacement valid % | stretches | rms error nm | largest nm | std nm | "
      "slope error % | within u % | off the peaks | s |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for name in args.scene or SCENES:
    scenario, kw = SCENES[name]
    for seed in seeds(args.seeds):
        path = out / f"{name.replace(' ', '_').replace(',', '').replace('/', 'p')}-{seed}.h5"
        if not path.exists():
            fmcw_cl.simulate(path, scenario, seed=seed, **kw)
        t0 = time.perf_counter()
        track = process(path, processor=be)
        secs = time.perf_counter() - t0
        with Capture(path) as cap:
            truth = cap.truth()
        print(f"| {name} | {seed} | {row(track, truth, scenario)} | {secs:.1f} |", flush=True)
