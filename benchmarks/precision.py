"""Precision of a static target against the Cramer-Rao bound, per-sample SNR +20 to -20 dB.

    python benchmarks/precision.py [--seconds 0.02] [--distance 0.3] [--png FILE] [--json FILE]

For each SNR: the valid share of the pairs, the standard deviation of their distances,
and two Cramer-Rao bounds for the distance of one pair (two half-sweeps averaged):
- *raw*: every raw sample of the half-sweep. The beat is A_n cos(2 pi nu(t_n) tau + phi)
  in white noise sigma, A_n following the laser's power, phi unknown; the Fisher
  information of tau is sum_n A_n^2 (2 pi (nu_n - mean nu))^2 / (2 sigma^2).
- *N points*: the N resampled points at uniform optical frequency, a tone of
  amplitude A (mid-sweep) in white noise sigma (the cubic resampling keeps about
  sigma per point): var(f) >= 12 / ((2 pi)^2 eta N (N^2 - 1)), eta = A^2 / (2 sigma^2).
The pipeline's std over the raw bound is the figure of merit; `--png` draws both. Where
the pipeline integrates K half-sweeps of a direction (weak echoes, chosen from the SNR),
both bounds are those of K pairs (sqrt(K) lower).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import crb_pair_m, truth_at
from fmcw_cl.options import Options
from fmcw_cl.physics import C
from fmcw_cl.simulator import SimulationConfig, simulate_capture, static

SNRS_DB = tuple(range(20, -25, -5))


def bounds(cfg: SimulationConfig, snr_db: float, points: int = 1000) -> tuple[float, float]:
    """(raw, N-point) Cramer-Rao bounds of one pair's distance (m, standard deviation)
    at per-sample SNR `snr_db` (the target's at 0.3 m mid-sweep), for a target within
    the echo's 1/R region (the amplitude of --snr-db's definition)."""
    m = cfg.modulation
    samples = int(round(m.period_s / 2 * cfg.sample_rate_hz))
    current = m.current_min_a + (m.current_max_a - m.current_min_a) * (np.arange(samples) + 0.5) / samples
    nu = cfg.laser.frequency(current)
    eta = 10 ** (snr_db / 10)                      # A_mid^2 / (2 sigma^2)
    amp2 = cfg.laser.relative_power(current) ** 2   # (A_n / A_mid)^2
    info_tau = 2 * eta * np.sum(amp2 * (2 * np.pi * (nu - np.average(nu, weights=amp2))) ** 2) / 2
    raw = C / 2 / np.sqrt(info_tau) / np.sqrt(2)
    return raw, crb_pair_m(eta, points, abs(nu[-1] - nu[0]))


def measure(tmp: Path, snr_db: float, seconds: float, distance: float, seed: int) -> dict:
    cfg = SimulationConfig(snr_db=snr_db)
    path = tmp / f"snr{snr_db:+g}.h5"
    simulate_capture(path, static(seconds, distance), seconds, seed=seed, config=cfg)
    track = process(path, Options())
    with Capture(path) as cap:
        r, _, _ = truth_at(cap.truth(), track.time_s)
    err = (track.distance_m - r)[track.valid]
    # an integrated pair holds K half-sweeps of each direction: its bounds are sqrt(K) lower
    k = int(track.attrs["integrated_sweeps_max"])
    raw, npt = (b / np.sqrt(k) for b in bounds(cfg, snr_db))
    std = float(np.std(err)) if err.size > 2 else float("nan")
    return {"snr_db": snr_db, "pairs": int(track.pairs), "valid_share": float(np.mean(track.valid)),
            "integrated": k, "std_m": std, "bias_m": float(np.mean(err)) if err.size else float("nan"),
            "crb_raw_m": raw, "crb_points_m": npt, "over_raw": std / raw, "over_points": std / npt}


def picture(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    snr = [r["snr_db"] for r in rows]
    fig, (ax, bx) = plt.subplots(2, 1, sharex=True, figsize=(7, 6.5), constrained_layout=True)
    ax.semilogy(snr, [1e6 * r["std_m"] for r in rows], "o-", label="fmcw-cl: std of valid pairs")
    ax.semilogy(snr, [1e6 * r["crb_raw_m"] for r in rows], "k--", label="Cramer-Rao, every raw sample")
    ax.semilogy(snr, [1e6 * r["crb_points_m"] for r in rows], "k:",
                label="Cramer-Rao, N = 1000 resampled points")
    for r in rows:
        if r["integrated"] > 1:
            ax.annotate(f"K={r['integrated']}", (r["snr_db"], 1e6 * r["std_m"]), fontsize=7,
                        textcoords="offset points", xytext=(4, 4))
    ax.set_ylabel("distance std per output (µm)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title("static target at 0.3 m: precision against the physical limit")
    bx.plot(snr, [100 * r["valid_share"] for r in rows], "o-", color="C2")
    bx.set_ylabel("valid pairs (%)")
    bx.set_xlabel("per-sample SNR of the target (dB)")
    bx.grid(alpha=0.3)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=0.02)
    ap.add_argument("--distance", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=300)
    ap.add_argument("--png", type=Path)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    print("| SNR dB | pairs | valid % | K | std um | CRB raw um | CRB N pts um | std / CRB raw "
          "| std / CRB N |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, snr in enumerate(SNRS_DB):
            r = measure(Path(tmp), snr, args.seconds, args.distance, args.seed + k)
            rows.append(r)
            print(f"| {snr:+d} | {r['pairs']} | {100 * r['valid_share']:.1f} | {r['integrated']} | "
                  f"{1e6 * r['std_m']:.3f} | "
                  f"{1e6 * r['crb_raw_m']:.3f} | {1e6 * r['crb_points_m']:.3f} | {r['over_raw']:.2f} | "
                  f"{r['over_points']:.2f} |", flush=True)
    if args.png:
        picture(rows, args.png)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
