"""What a GPU user runs (docs/gpu.md), and what a session lent a GPU reports in
benchmarks/README.md: on one device,

    python benchmarks/gpu.py [--device nvidia] [--seconds 1] [--batch 8] [--json FILE]

1. every kernel against its numpy twin on the device (fmcw_cl.opencl.selftest);
2. `fmcw-cl bench`'s table for numpy and the device (`--backends`; per stage, end to end, host CPU
   per second of capture, launches and copies per chunk);
3. a batch: `--batch` captures of the guide rail, `--seconds` each, converted by one
   warm backend as `fmcw-cl process` does (batch.process_each), `--workers` at once
   (1 and 2 unless given; each count twice, in order and back, the best of the two):
   the aggregate multiple of real time, file to track (page cache); and three
   of them alone, each the second of two conversions by one warm backend. The backend
   warms up on captures of its own, so every capture of the batch is one it has not
   seen (where a kernel build waits for a new size, it shows: `benchmarks/README.md`,
   part 3). `--batch-only` skips 1 and 2;
4. with `--processes N [N ...]` (Dask installed: `pip install ".[cluster]"`), the same
   batch on `fmcw-cl process --scheduler local:N`'s cluster of N worker processes, each
   with its own context on the device: a host of many cores runs N captures' host steps
   at once, where the threads of 3 share one interpreter. Best of two runs after one
   that warms the workers up.

The captures (the bench's and the batch's) are written first, at once, a thread each
(a 1 s capture takes a core 20-40 s), into `--captures` where given, which keeps them for
the next run. Before them, a 20 ms jump is converted on the device and by numpy and the
tracks compared, so that a device that crashes or disagrees says so in seconds (on
2026-12-04 every conversion crashed on an H200 after 90 s of writing captures);
faulthandler prints where a crash happened, and `--json` is written after each part.
Runs on any OpenCL device (PoCL too); the figures are ratios within one run.
"""

from __future__ import annotations

import argparse
import faulthandler
import json
import os
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fmcw_cl.backend import make_processor
from fmcw_cl.batch import process_each
from fmcw_cl.bench import captures as bench_captures
from fmcw_cl.bench import run
from fmcw_cl.engine import process
from fmcw_cl.opencl.selftest import check
from fmcw_cl.options import Options
from fmcw_cl.simulator import jump, rail, simulate_captures


def captures(seconds: float, count: int, folder: Path) -> list[dict]:
    """`count` captures of the guide rail of `seconds` (seeds 100 on), and two more for
    warming up, last: jobs of `simulate_captures`."""
    return [{"path": folder / f"rail{k}_{seconds:g}s.h5", "trajectory": rail(seconds + 0.1),
             "duration_s": seconds, "seed": 100 + k, "start_s": 0.1} for k in range(count + 2)]


def smoke(device: str | None, folder: Path) -> dict:
    """A 20 ms jump converted on the device and by numpy: whether the valid pairs agree
    and the largest distance apart (m) where both are valid."""
    (path,) = simulate_captures([{"path": folder / "smoke_jump.h5", "trajectory": jump(0.07),
                                  "duration_s": 0.02, "seed": 5, "start_s": 0.04}])
    got = process(path, Options(), make_processor("opencl", device))
    want = process(path, Options(), make_processor("numpy"))
    both = got.valid & want.valid
    apart = float(np.max(np.abs(got.distance_m[both] - want.distance_m[both]), initial=0.0))
    return {"device": device or "auto", "pairs": int(got.valid.size),
            "valid_equal": bool(np.array_equal(got.valid, want.valid)), "max_distance_apart_m": apart}


def batch(device: str | None, seconds: float, paths: list[Path], counts: Sequence[int] = (1, 2)
          ) -> list[dict]:
    """Aggregate throughput of the captures of `paths` (`captures`) converted by
    batch.process_each (`fmcw-cl process`), each of `counts` at once (the device's own
    choice is the backend's `batch_workers`), in order and back: a row each, the best of
    its two runs."""
    count = len(paths) - 2
    counts = list(dict.fromkeys(min(c, count) for c in counts))      # no more at once than captures
    be = make_processor("opencl", device)
    # warm: programs built, every worker's buffers sized, on captures of their own
    list(process_each(paths[count:], Options(), be, workers=max(counts)))
    best: dict[int, dict] = {}
    for workers in [*counts, *counts[::-1]]:
        wall, cpu, main = time.perf_counter(), os.times(), time.thread_time()
        for _, got in process_each(paths[:count], Options(), be, workers):
            if isinstance(got, Exception):
                raise got
        wall, main = time.perf_counter() - wall, time.thread_time() - main
        cpu = sum(os.times()[:2]) - sum(cpu[:2])
        total = seconds * count
        row = {"device": be.device, "captures": count, "capture_seconds": total, "workers": workers,
               "default": workers == be.batch_workers, "wall_s": wall, "real_time_multiple": total / wall,
               "process_cpu_cores": cpu / wall,
               # the host work that bounds a GPU: the converting thread's (one at a time)
               "host_cpu_ms_per_s": 1e3 * main / total if workers == 1 else float("nan")}
        if workers not in best or wall < best[workers]["wall_s"]:
            best[workers] = row
    return [best[w] for w in counts]


def alone(device: str | None, seconds: float, paths: list[Path], count: int = 3) -> list[dict]:
    """Single captures file to track (`engine.process`, as `fmcw-cl process` of one): the
    first `count` of the batch's (`paths` but the last two, which warm the backend up),
    each converted twice by one warm backend, the second timed: a row each."""
    be = make_processor("opencl", device)
    process(paths[-1], Options(), be)                   # warm: programs built, buffers sized
    rows = []
    for path in paths[:-2][:count]:
        for _ in range(2):
            wall = time.perf_counter()
            process(path, Options(), be)
            wall = time.perf_counter() - wall
        rows.append({"device": be.device, "capture": path.name, "wall_s": wall,
                     "real_time_multiple": seconds / wall})
    return rows


def processes(device: str | None, seconds: float, paths: list[Path], n: int, tmp: Path) -> dict:
    """The captures of `paths` but the last two converted on a `local:n` Dask cluster
    (cluster.run_batch, as `fmcw-cl process --scheduler local:n`): the best of two runs
    after one that warms the workers up (their contexts and programs)."""
    from fmcw_cl.cluster import connect, run_batch

    todo, out = paths[:-2], tmp / f"tracks{n}"
    out.mkdir(exist_ok=True)
    client = connect(f"local:{n}")
    try:
        walls = []
        for _ in range(3):
            wall = time.perf_counter()
            for got in run_batch(client, todo, out, Options(), "opencl", device):
                if "error" in got:
                    raise RuntimeError(got["error"])
            walls.append(time.perf_counter() - wall)
    finally:
        client.close()
    wall = min(walls[1:])
    total = seconds * len(todo)
    return {"device": device or "auto", "captures": len(todo), "capture_seconds": total, "processes": n,
            "wall_s": wall, "real_time_multiple": total / wall, "warm_up_wall_s": walls[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default=None, help="OpenCL device (see `fmcw-cl devices`)")
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--batch-only", action="store_true", help="only the batch (no check, no bench table)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="captures of the batch at once")
    ap.add_argument("--backends", nargs="+", default=["numpy", "opencl"], choices=["numpy", "opencl"],
                    help="the bench table's backends (numpy's rows take minutes for a 1 s capture)")
    ap.add_argument("--processes", type=int, nargs="*", default=[],
                    help="also the batch on local:N Dask clusters of these N (needs Dask)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--captures", type=Path, help="folder where the bench's and the batch's captures are "
                    "kept and found (default: a removed temp dir)")
    args = ap.parse_args()
    faulthandler.enable()
    out: dict = {}

    def save(key: str, value) -> None:
        out[key] = value
        if args.json:
            args.json.write_text(json.dumps(out, indent=2))

    with tempfile.TemporaryDirectory() as tmp:
        folder = args.captures or Path(tmp)
        first = smoke(args.device, Path(tmp))
        save("smoke", first)
        print(f"smoke test, a 20 ms jump: {first['pairs']} pairs, valid pairs "
              f"{'as' if first['valid_equal'] else 'NOT as'} numpy's, distances within "
              f"{first['max_distance_apart_m']:.1e} m", flush=True)
        jobs = captures(args.seconds, args.batch, folder)
        bench_jobs = [] if args.batch_only else bench_captures(args.seconds, folder)
        paths = simulate_captures([*bench_jobs, *jobs])[len(bench_jobs):]      # all at once
        rows = []
        if not args.batch_only:
            check(args.device)
            rows = run(args.seconds, 1000, args.backends, args.device, folder=folder)
            save("bench", rows)
            print("\n| backend | stage | s | x real time | of end to end | host CPU ms per s |")
            print("|---|---|---|---|---|---|")
        for r in rows:
            host = f"{r['host_cpu_ms_per_s']:.0f}" if "host_cpu_ms_per_s" in r else ""
            share = r["share_of_end_to_end"]          # NaN: a scene's row, apart from the shares
            print(f"| {r['backend']} | {r['stage']} | {r['seconds']:.4f} | {r['real_time_multiple']:.2f} | "
                  f"{f'{share:.0%}' if share == share else ''} | {host} |")
        got = batch(args.device, args.seconds, paths, args.workers)
        save("batch", got)
        for b in got:
            host = f", host CPU {b['host_cpu_ms_per_s']:.0f} ms per s" if b["workers"] == 1 else ""
            print(f"\nbatch: {b['captures']} captures of {args.seconds:g} s on {b['device']}, {b['workers']} "
                  f"at once{' (its default)' if b['default'] else ''}: {b['wall_s']:.2f} s, "
                  f"{b['real_time_multiple']:.2f}x real time, {b['process_cpu_cores']:.2f} cores busy{host}",
                  flush=True)
        singles = alone(args.device, args.seconds, paths)
        save("alone", singles)
        walls = ", ".join(f"{r['wall_s']:.3f}" for r in singles)
        multiples = ", ".join(f"{r['real_time_multiple']:.2f}" for r in singles)
        print(f"one capture alone: {walls} s ({multiples}x real time)", flush=True)
        spread = []
        for n in args.processes:
            spread.append(processes(args.device, args.seconds, paths, n, Path(tmp)))
            save("processes", spread)
            p = spread[-1]
            print(f"batch on local:{n}: {p['captures']} captures of {args.seconds:g} s: {p['wall_s']:.2f} s, "
                  f"{p['real_time_multiple']:.2f}x real time (warm-up run {p['warm_up_wall_s']:.2f} s)",
                  flush=True)

if __name__ == "__main__":
    main()
