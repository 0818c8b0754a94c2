"""Throughput of `process --scheduler local:N` against worker count, on this machine.

    python benchmarks/cluster.py [--captures 4] [--seconds 0.1] [--workers 1 2]

Simulates a batch of static captures, converts it on one machine (no Dask) and on a
LocalCluster of N worker processes (the cluster's start-up is timed apart), and prints
a Markdown table: capture seconds converted per wall second and the speed-up.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from fmcw_cl.cluster import connect, run_batch
from fmcw_cl.engine import process
from fmcw_cl.options import Options
from fmcw_cl.processor import NumpyProcessor
from fmcw_cl.simulator import simulate_capture, static
from fmcw_cl.track import track_path, write_track


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--captures", type=int, default=4)
    ap.add_argument("--seconds", type=float, default=0.1)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        caps = []
        for k in range(args.captures):
            p = d / f"c{k}.h5"
            simulate_capture(p, static(args.seconds, 0.15 + 0.05 * k), args.seconds, seed=k)
            caps.append(p)
        total = args.captures * args.seconds
        options = Options()
        out = d / "local"
        out.mkdir()
        t0 = time.perf_counter()
        for p in caps:
            write_track(track_path(out, p), process(p, options, NumpyProcessor()))
        base = time.perf_counter() - t0
        rows = [("one process, no Dask", 0.0, base)]
        for n in args.workers:
            t0 = time.perf_counter()
            client = connect(f"local:{n}")
            client.wait_for_workers(n)
            start = time.perf_counter() - t0
            out = d / f"dask{n}"
            out.mkdir()
            t0 = time.perf_counter()
            results = list(run_batch(client, caps, out, options, "numpy"))
            wall = time.perf_counter() - t0
            assert not any("error" in r for r in results)
            client.close()
            client.cluster.close()
            rows.append((f"local:{n}", start, wall))
    print(f"{args.captures} captures of {args.seconds:g} s, numpy backend\n")
    print("| run | cluster start (s) | convert wall (s) | capture s per wall s | speed-up |")
    print("|---|---:|---:|---:|---:|")
    for name, start, wall in rows:
        print(f"| {name} | {start:.1f} | {wall:.1f} | {total / wall:.4f} | {base / wall:.2f}x |")


if __name__ == "__main__":
    main()
