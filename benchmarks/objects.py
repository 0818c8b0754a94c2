"""Scenes of several objects: every object its own track (markdown rows on stdout).

    python benchmarks/objects.py [--seeds 1-3] [--out DIR]

The scenes of `fmcw_cl.simulator.several` (lab SNR, speckle): two movers (a leg and a
swaying cable, weaker and stronger), a rail passing a swaying object, a hand in the
beam before a target at rest, an occlusion with return, a target through a wall, a
foot resting at a window, a short slow capture. Default options, the default backend.
Per scene and seed: the objects found (kind, span); for each true object, the share of
its visible periods some object holds within 2 mm ("tracked", the best object's) and
how many objects hold it; "wrong": valid pairs of any object more than 2 mm from the
truth they follow (must be 0); the target's truth; the conversion's time.
"""

import argparse
import time

from scratch import folder, seeds

from fmcw_cl import objects
from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.evaluate import object_scores
from fmcw_cl.simulator import several

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--seeds", default="1-3", help="seeds, as A-B (default 1-3)")
parser.add_argument("--out", default=None, help="folder for the captures, kept (default: a removed temp dir)")
parser.add_argument("--scene", action="append", help="only these scenes (names of several.SCENES)")
args = parser.parse_args()
out = folder(args.out, "fmcw-objects-")
be = make_processor("auto")
print("| scene | seed | objects (kind, span m) | true objects tracked % (holders) | wrong | target | s |")
print("|---|---|---|---|---|---|---|")
total_wrong = 0
for name in args.scene or several.SCENES:
    for seed in seeds(args.seeds):
        path = out / f"{name.replace(' ', '_').replace(',', '').replace('+', 'p')}-{seed}.h5"
        if not path.exists():
            several.write(name, path, seed)
        t0 = time.perf_counter()
        track = process(path, processor=be)
        secs = time.perf_counter() - t0
        with Capture(path) as cap:
            truths = cap.truth_objects()
        scores = object_scores(track, truths)
        found = [objects.describe(o) for o in track.objects]
        follows = {s["id"]: s["truth"] for s in scores}
        wrong = sum(s["wrong"] for s in scores)
        total_wrong += wrong
        cells = []
        for k, truth in enumerate(truths):
            holders = [s for s in scores if s["truth"] == k]
            best = max((s["tracked"] for s in holders), default=0.0)
            cells.append(f"{truth.kind[0]}{k}: {100 * best:.0f} ({len(holders)})")
        target = follows.get(int(track.attrs["target_object"]))
        print(f"| {name} | {seed} | {'; '.join(found)} | {', '.join(cells)} | {wrong} | "
              f"truth {target} | {secs:.1f} |", flush=True)
print(f"\nwrong valid pairs in all: {total_wrong}")
