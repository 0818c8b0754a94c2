"""Accuracy table per scenario on the project's simulator (markdown on stdout).

    python benchmarks/accuracy.py [--seed K] [--json FILE]

Rows: static targets across the range (N = 1000 and N = 2048), the guide rail, the
jump, and the jump with the paper's method alone (--no-dechirp), so that the gain of
the Doppler de-chirp tracker is visible.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from fmcw_cl.capture import Capture
from fmcw_cl.engine import Options, process
from fmcw_cl.evaluate import accuracy
from fmcw_cl.simulate import jump, rail, simulate_capture, static

ROWS = [  # (label, scenario factory, duration s, points, dechirp)
    *[(f"static {d:.2f} m", lambda T, d=d: static(T, d), 0.05, 1000, True)
      for d in (0.05, 0.15, 0.30, 0.45)],
    *[(f"static {d:.2f} m", lambda T, d=d: static(T, d), 0.05, 2048, True) for d in (0.60, 0.80)],
    ("rail", rail, 0.4, 1000, True),
    ("jump", jump, 0.3, 1000, True),
    ("jump, paper's method (--no-dechirp)", jump, 0.3, 1000, False),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    out = []
    print("| scenario | N | pairs | valid % | dist bias mm | dist std mm | dist p95 mm | "
          "dist max mm | vel p95 m/s | acc p95 m/s^2 | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        made: dict[tuple, Path] = {}
        for i, (label, scene, duration, points, dechirp) in enumerate(ROWS):
            key = (label.split(",")[0], duration)
            if key not in made:
                made[key] = Path(tmp) / f"{i}.h5"
                simulate_capture(made[key], scene(duration), duration, seed=args.seed + i)
            started = time.perf_counter()
            track = process(made[key], Options(points=points, dechirp=dechirp))
            secs = time.perf_counter() - started
            with Capture(made[key]) as cap:
                a = accuracy(track, cap.truth())
            a.update(scenario=label, points=points, seconds=secs)
            out.append(a)
            print(f"| {label} | {points} | {a['pairs']} | {100 * a['valid_share']:.2f} | "
                  f"{1e3 * a['distance_bias_m']:+.4f} | {1e3 * a['distance_std_m']:.4f} | "
                  f"{1e3 * a['distance_p95_m']:.4f} | {1e3 * a['distance_max_m']:.3f} | "
                  f"{a['velocity_p95_mps']:.4f} | {a['acceleration_p95_mps2']:.2f} | {secs:.1f} |",
                  flush=True)
    if args.json:
        args.json.write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
