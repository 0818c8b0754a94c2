"""The distance scale's bias against its stated uncertainty, over many G(I) tables.

    python benchmarks/distance_scale.py [--tables 200] [--table-noise-mhz 20]

Each table is a new draw of the laser's offline G(I) measurement (25 points, 20 MHz rms
by default); each capture a static target at a distance drawn in 0.1-0.8 m, 10 ms
(200 pairs; the simulator's default noise: the scale's bias dominates the mean), N = 2048
(unambiguous to 0.94 m). The bias is the valid pairs' mean error against /truth; the
stated sigma is the track's `scale_uncertainty_m`. Prints the share within 2 and 3
stated sigma, and the bias at 0.7 m (bias over distance times 0.7 m) by percentile.
"""

from __future__ import annotations

import argparse

import numpy as np
from scratch import folder

from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import accuracy
from fmcw_cl.options import Options
from fmcw_cl.simulator import SimulationConfig, simulate_capture, static


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tables", type=int, default=200)
    ap.add_argument("--table-noise-mhz", type=float, default=20.0)
    args = ap.parse_args()
    tmp = folder(None, "fmcw-distance-")
    be = make_processor("auto")
    cfg = SimulationConfig(table_noise_hz=args.table_noise_mhz * 1e6)
    bias, sigma, dist = [], [], []
    for seed in range(args.tables):
        d = float(np.random.default_rng(10_000 + seed).uniform(0.1, 0.8))
        path = tmp / "static.h5"
        simulate_capture(path, static(0.01, d), 0.01, seed=seed, config=cfg)
        track = process(path, Options(points=2048), be)
        with Capture(path) as cap:
            acc = accuracy(track, cap.truth())
        bias.append(acc["distance_bias_m"])
        sigma.append(track.attrs["scale_uncertainty_m"])
        dist.append(d)
    bias, sigma, dist = map(np.asarray, (bias, sigma, dist))
    ratio = np.abs(bias) / sigma
    at07 = np.abs(bias) / dist * 0.7 * 1e3
    print(f"{args.tables} tables, {args.table_noise_mhz:g} MHz, 0.1-0.8 m, {be.device}")
    print(f"|bias| <= 2 stated sigma: {np.mean(ratio <= 2):.1%}; <= 3 sigma: {np.mean(ratio <= 3):.1%}")
    print(f"stated sigma at 0.7 m: median {np.median(sigma / dist) * 0.7e3:.3f} mm")
    print("|bias| at 0.7 m, mm: " + ", ".join(f"p{p} {np.percentile(at07, p):.3f}" for p in (50, 90, 95, 99))
          + f", max {at07.max():.3f}")


if __name__ == "__main__":
    main()
