"""Time and peak memory of `fmcw-cl process` against capture length.

    python benchmarks/scale.py [--lengths 1 2 5 10] [--backends numpy opencl] [--dir DIR]

A 1 s static capture is simulated once (20 000 whole periods) and tiled into longer
captures (the tiles join seamlessly: whole periods, same target). Each conversion runs
in a fresh process whose peak resident memory (VmHWM) is read back, and its largest
anonymous part (RssAnon, sampled every 20 ms: VmHWM also counts the pages of a file
mapped while it is read in place, `Capture` `in_place`, which the kernel may drop).
Prints a Markdown table: time should grow linearly with length, anonymous memory stay flat.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import h5py
from scratch import folder

from fmcw_cl.capture import Capture
from fmcw_cl.capture_writer import CaptureWriter
from fmcw_cl.simulator import simulate_capture, static

# Peak memory: VmHWM of the process's own address space. ru_maxrss would not do: Linux
# carries the parent's high-water mark through fork and exec, and the parent holds the
# simulated capture.
CHILD = """
import json, resource, sys, threading, time
from fmcw_cl.engine import process
from fmcw_cl.backend import make_processor

def status_kb(key):
    try:
        return int(open("/proc/self/status").read().split(key + ":")[1].split()[0])
    except (OSError, IndexError):
        return 0

anon, done = [0], threading.Event()
def sample():       # the largest anonymous part seen (mapped file pages are RssFile)
    while not done.wait(0.02):
        anon[0] = max(anon[0], status_kb("RssAnon"))
threading.Thread(target=sample, daemon=True).start()
t = time.perf_counter()
track = process(sys.argv[1], processor=make_processor(sys.argv[2]))
seconds = time.perf_counter() - t
done.set()
peak_kb = status_kb("VmHWM") or resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"seconds": seconds, "pairs": track.pairs, "valid": float(track.valid.mean()),
                  "rss_mb": peak_kb / 1024, "anon_mb": max(anon[0], status_kb("RssAnon")) / 1024}))
"""


def tile(src: Path, dst: Path, times: int) -> None:
    with Capture(src) as cap, h5py.File(src) as f:
        info = cap.info
        table = f["laser/tuning_current_a"][()], f["laser/tuning_frequency_hz"][()]
        n = info.samples
        with CaptureWriter(dst, n * times, info.sample_rate_hz, info.bits, info.modulation, *table) as w:
            step = 1 << 24
            for a in range(0, n, step):
                beat, sync = cap.read(a, a + step)
                for k in range(times):
                    w.write(k * n + a, beat, sync)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lengths", type=int, nargs="+", default=[1, 2, 5, 10])
    ap.add_argument("--backends", nargs="+", default=["numpy", "opencl"])
    ap.add_argument("--dir", type=Path, default=None, help="captures kept here (default: a removed temp dir)")
    args = ap.parse_args()
    d = folder(args.dir, "fmcw-scale-")
    base = d / "static_1s.h5"
    if not base.exists():
        simulate_capture(base, static(1.0, 0.3), 1.0, seed=1)
    rows = []
    for length in args.lengths:
        path = base if length == 1 else d / f"static_{length}s.h5"
        if not path.exists():
            tile(base, path, length)
        for backend in args.backends:
            t = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", CHILD, str(path), backend],
                                 capture_output=True, text=True, check=True)
            got = json.loads(out.stdout.strip().splitlines()[-1])
            got.update(length=length, backend=backend, wall=time.perf_counter() - t,
                       gb=path.stat().st_size / 1e9)
            rows.append(got)
            print(json.dumps(got), file=sys.stderr, flush=True)
    print("| capture (s) | file (GB) | backend | convert (s) | s per capture s | peak resident (MB) "
          "| peak anonymous (MB) | pairs | valid |")
    print("|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['length']} | {r['gb']:.1f} | {r['backend']} | {r['seconds']:.1f} | "
              f"{r['seconds'] / r['length']:.1f} | {r['rss_mb']:.0f} | {r['anon_mb']:.0f} | {r['pairs']} | "
              f"{100 * r['valid']:.1f} % |")


if __name__ == "__main__":
    main()
