"""Accuracy table per scenario on the project's simulator (markdown on stdout).

    python benchmarks/accuracy.py [--seed K] [--json FILE]

Rows: static targets across the range (N = 1000 and N = 2048), the guide rail, the
jump, and the jump with the paper's method alone (--no-dechirp), so that the gain of
the Doppler de-chirp tracker is visible; then, for a laser whose thermal tuning lags
by 0.5, 2 and 5 us, a static target and the jump with the static G(I) table and with a
chirp calibrated on another static capture (`--rows lag` for these alone); then real
scenes at a lab's SNR (0 dB per sample at 0.3 m): the jump alone, behind it a wall
stronger than the target in flight (without and with --max-range), with 3 ms speckle
fading, landing at 0.06 m, and a static target with a second reflector
(`--rows scenes` for these alone).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from fmcw_cl.calibration import measure_chirp
from fmcw_cl.capture import Capture
from fmcw_cl.chirp import write_chirp
from fmcw_cl.engine import process
from fmcw_cl.evaluate import accuracy
from fmcw_cl.options import Options
from fmcw_cl.simulator import SimulationConfig, jump, rail, simulate_capture, static

ROWS = [  # (label, scenario factory, duration s, points, dechirp)
    *[(f"static {d:.2f} m", lambda T, d=d: static(T, d), 0.05, 1000, True)
      for d in (0.05, 0.15, 0.30, 0.45)],
    *[(f"static {d:.2f} m", lambda T, d=d: static(T, d), 0.05, 2048, True) for d in (0.60, 0.80)],
    ("rail", rail, 0.4, 1000, True),
    ("jump", jump, 0.3, 1000, True),
    ("jump, paper's method (--no-dechirp)", jump, 0.3, 1000, False),
]
LAGS_US = (0.5, 2.0, 5.0)
SCENES = [  # (label, trajectory factory, duration s, SimulationConfig fields, Options fields)
    ("jump, 0 dB", jump, 0.3, {}, {}),
    ("jump + wall 0.42 m, 0 dB", jump, 0.3, {"reflectors": ((0.42, 800.0),)}, {}),
    ("jump + wall 0.42 m, 0 dB, --max-range 0.40", jump, 0.3, {"reflectors": ((0.42, 800.0),)},
     {"max_range": 0.40}),
    ("jump, 0 dB, speckle 3 ms", jump, 0.3, {"speckle_s": 3e-3}, {}),
    ("jump, -3 dB, speckle 3 ms", jump, 0.3, {"speckle_s": 3e-3, "snr_db": -3.0}, {}),
    ("jump landing at 0.06 m, 0 dB", lambda T: jump(T, ground_m=0.06), 0.3, {}, {}),
    ("static 0.21 m + reflector 0.37 m, 0 dB", lambda T: static(T, 0.21), 0.05,
     {"reflectors": ((0.37, 400.0),)}, {}),
]


CAL_SNRS_DB = (0.0, -10.0)   # calibrations also taken at a lab's SNR (2000 periods each)


def lag_rows(tmp: Path, seed: int):
    """(label, capture, options) of the thermal-lag rows; the calibration is made on a
    static capture at 0.3 m of the same laser, other seed: clean (400 periods), and at
    0 and -10 dB per sample (2000 periods)."""
    for k, lag in enumerate(LAGS_US):
        cfg = replace(SimulationConfig(), thermal_lag_s=lag * 1e-6)
        chirps = {}
        for j, snr in enumerate((None, *CAL_SNRS_DB)):
            cal = tmp / f"cal{k}_{j}.h5"
            duration = 0.02 if snr is None else 0.1
            simulate_capture(cal, static(duration, 0.3), duration, seed=seed + 50 + 10 * j + k,
                             config=replace(cfg, snr_db=snr))
            label = "calibrated chirp" if snr is None else f"chirp calibrated at {snr:g} dB"
            chirps[label] = str(write_chirp(tmp / f"chirp{k}_{j}.h5", measure_chirp(cal, 0.3)))
        for name, scene, duration in (("static 0.18 m", lambda T: static(T, 0.18), 0.05),
                                      ("jump", jump, 0.3)):
            cap = tmp / f"lag{k}_{name.split()[0]}.h5"
            simulate_capture(cap, scene(duration), duration, seed=seed + 60 + k, config=cfg)
            yield f"{name}, lag {lag:g} us, G(I) table", cap, Options()
            for label, chirp in chirps.items():
                yield f"{name}, lag {lag:g} us, {label}", cap, Options(chirp=chirp)


def scene_rows(tmp: Path, seed: int):
    """(label, capture, options) of the real-scene rows; a capture per scene and seed."""
    made: dict[tuple, Path] = {}
    for i, (label, scene, duration, cfg, opts) in enumerate(SCENES):
        key = (label.split(", --")[0], duration)
        if key not in made:
            made[key] = tmp / f"scene{i}.h5"
            config = SimulationConfig(**{"snr_db": 0.0, **cfg})
            simulate_capture(made[key], scene(duration), duration, seed=seed + 80 + i, config=config)
        yield label, made[key], Options(**opts)


def rows(tmp: Path, args):
    """(label, capture, options) of every row asked for; captures made once per scene."""
    if args.rows in ("all", "base"):
        made: dict[tuple, Path] = {}
        for i, (label, scene, duration, points, dechirp) in enumerate(ROWS):
            key = (label.split(",")[0], duration)
            if key not in made:
                made[key] = tmp / f"{i}.h5"
                simulate_capture(made[key], scene(duration), duration, seed=args.seed + i)
            yield label, made[key], Options(points=points, dechirp=dechirp)
    if args.rows in ("all", "lag"):
        yield from lag_rows(tmp, args.seed)
    if args.rows in ("all", "scenes"):
        yield from scene_rows(tmp, args.seed)


def rival(track) -> str:
    """The warning's facts: another echo's distance and level over the target, or -."""
    d, db = track.attrs.get("rival_echo_m", np.nan), track.attrs.get("rival_echo_db", np.nan)
    return "-" if not np.isfinite(d) else f"{d:.3f} m, {db:+.1f} dB"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--rows", choices=["all", "base", "lag", "scenes"], default="all")
    args = ap.parse_args()
    out = []
    print("| scenario | N | pairs | valid % | dist bias mm | dist std mm | dist p95 mm | "
          "dist max mm | vel p95 m/s | acc p95 m/s^2 | rival echo | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for label, path, options in rows(Path(tmp), args):
            started = time.perf_counter()
            track = process(path, options)
            secs = time.perf_counter() - started
            with Capture(path) as cap:
                a = accuracy(track, cap.truth())
            a.update(scenario=label, points=options.points, seconds=secs)
            out.append(a)
            print(f"| {label} | {options.points} | {a['pairs']} | {100 * a['valid_share']:.2f} | "
                  f"{1e3 * a['distance_bias_m']:+.4f} | {1e3 * a['distance_std_m']:.4f} | "
                  f"{1e3 * a['distance_p95_m']:.4f} | {1e3 * a['distance_max_m']:.3f} | "
                  f"{a['velocity_p95_mps']:.4f} | {a['acceleration_p95_mps2']:.2f} | {rival(track)} | "
                  f"{secs:.1f} |", flush=True)
    if args.json:
        args.json.write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
