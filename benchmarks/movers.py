"""Random scenes of two movers hunted for valid pairs on the other object (a line each).

    python benchmarks/movers.py [--seed K] [--count N] [--only I ...] [--why] [--out DIR]

Each capture holds two movers whose ranges cross within it: two jumps 10-80 ms apart
(the second foot's ground within 10 mm), a rail's start against a glide, the jump and a
hand glided through its path, two glides at nearly equal speeds (opposite ways, or one
overtaking), a sway and a glide; the second mover -6..+6 dB against the target's 500
codes at 0.3 m; 50-300 ms around one crossing, at a lab's SNR (several.LAB_SCENE) on
three in four, else clean; each on its own seed. Default options, the default backend.
"wrong" counts the valid pairs of every object more than 2 mm from the truth it follows
(`evaluate.object_scores`); the lines that have any end in "<<<<"; "best" is each
mover's best object's share of its visible periods, "apart" of those where the other
lies more than 2 mm away (evaluate.ONE_M: closer, the two make one peak, which the
issue asks to be ambiguous); a capture that fails to convert says why. Reproducible: the draws follow
--seed, and `--only 7 24` converts those captures of the draw alone. `--why` adds a line
per capture: where each mover's visible periods went (`evaluate.untracked`, in %: held
by its best object / within 2 mm of the other mover / beside it within 10 mm / held by
another object / outside every band / unverified / missed), and the sums over the
captures at the end.
"""

from dataclasses import replace

import numpy as np
from scratch import draws

from fmcw_cl.backend import make_processor
from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.errors import FmcwError
from fmcw_cl.evaluate import UNTRACKED, best_held, object_scores, untracked
from fmcw_cl.simulator.scene import Trajectory, glide, jump, rail, sway
from fmcw_cl.simulator.several import LAB_SCENE
from fmcw_cl.simulator.writer import Mover, SimulationConfig, simulate_capture

SPAN_S = 0.7            # every trajectory tabulated over 0 .. SPAN_S
KINDS = ("two jumps", "rail against a glide", "jump and a hand", "two glides", "sway and a glide")


def shifted(off: float) -> Trajectory:
    """The jump `off` s ahead (at rest before its start)."""
    x = jump(SPAN_S + 0.2)

    def at(t, k):
        u = np.asarray(t) + off
        return np.where(u >= 0, x.at(np.maximum(u, 0.0))[k], 0.0)

    return Trajectory.from_velocity(0.0, SPAN_S, lambda t: at(t, 1), lambda t: at(t, 2),
                                    float(x.at(max(off, 0.0))[0]))


def glided(rng, a: float, b: float, speed: float, t0_hi: float) -> Trajectory:
    """A glide a -> b (m) at about `speed` (m/s), starting within 0 .. t0_hi s."""
    t0 = rng.uniform(0.0, t0_hi)
    return glide(SPAN_S, a, b, t0, t0 + min(2 * abs(b - a) / speed, 0.4))


def movers(kind: str, rng) -> tuple[Trajectory, Trajectory]:
    """The target's trajectory and the other mover's, of `kind`."""
    u = rng.uniform
    if kind == "two jumps":
        lag = u(0.01, 0.08) * rng.choice([-1, 1])
        return jump(SPAN_S), shifted(float(lag))
    if kind == "rail against a glide":
        v, travel = u(0.5, 4.0), u(0.15, 0.33)
        target = rail(SPAN_S, u(0.05, 0.10), v, float(np.clip(v * v / travel, 8.0, 120.0)), u(0.0, 0.12))
        return target, glided(rng, u(0.28, 0.40), u(0.05, 0.12), u(0.5, 4.0), 0.2)
    if kind == "jump and a hand":
        a, b = (u(0.30, 0.42), u(0.03, 0.06)) if rng.random() < 0.6 else (u(0.03, 0.06), u(0.30, 0.42))
        return jump(SPAN_S), glided(rng, a, b, u(0.5, 4.0), 0.25)
    if kind == "two glides":
        v = u(0.5, 4.0)
        if rng.random() < 0.5:          # opposite ways
            return (glided(rng, u(0.05, 0.12), u(0.30, 0.40), v, 0.15),
                    glided(rng, u(0.30, 0.40), u(0.05, 0.12), v * u(0.9, 1.1), 0.15))
        a = u(0.05, 0.12)               # one way, one overtaking the other
        ends = [(a, a + u(0.2, 0.3)), (a + (d := u(-0.03, 0.03)), a + d + u(0.2, 0.3))]
        if rng.random() < 0.5:
            ends = [(b, a) for a, b in ends]
        return glided(rng, *ends[0], v, 0.15), glided(rng, *ends[1], v * u(1.05, 1.3), 0.15)
    swaying = sway(SPAN_S, u(0.15, 0.32), u(0.01, 0.06), u(1.0, 6.0), u(0, 2 * np.pi))
    a, b = (u(0.05, 0.1), u(0.35, 0.42)) if rng.random() < 0.5 else (u(0.35, 0.42), u(0.05, 0.1))
    other = glided(rng, a, b, u(0.5, 4.0), 0.25)
    return (swaying, other) if rng.random() < 0.5 else (other, swaying)


def around_a_crossing(a: Trajectory, b: Trajectory, rng) -> tuple[float, float] | None:
    """A capture's (start, duration) s holding one of the movers' crossings, both within
    0.03-0.5 m throughout; None where they do not cross."""
    t = np.arange(0.0, 0.6, 1e-4)
    ra, rb = a.distance_at(t), b.distance_at(t)
    cross = t[np.flatnonzero(np.sign(ra - rb)[:-1] != np.sign(ra - rb)[1:])]
    cross = cross[(cross > 0.01) & (cross < 0.55)]
    if not cross.size:
        return None
    span = float(rng.uniform(0.05, 0.30))
    c = float(rng.choice(cross))
    lo, hi = max(0.0, c - span + 0.01), min(c - 0.01, 0.6 - span)
    if hi < lo:
        return None
    start = float(rng.uniform(lo, hi))
    inside = (t >= start) & (t <= start + span)
    if min(ra[inside].min(), rb[inside].min()) < 0.03 or max(ra[inside].max(), rb[inside].max()) > 0.5:
        return None
    return start, span


args, out, rng = draws(__doc__, "fmcw-movers-", 1, 40,
                       ("--only", dict(type=int, nargs="*", help="convert these captures of the draw alone")),
                       ("--why", dict(action="store_true", help="where each mover's untracked periods went")))
be = make_processor("auto")
total = failed = 0
went = np.zeros(len(UNTRACKED))      # periods, summed over the movers of every capture
at80 = np.zeros(2, int)              # movers at 80 % of their periods: all, apart
for i in range(args.count):
    kind = KINDS[i % len(KINDS)]
    while (drawn := movers(kind, rng)) and (span := around_a_crossing(*drawn, rng)) is None:
        pass
    db = float(rng.uniform(-6, 6))
    lab = bool(rng.random() < 0.75)
    cfg = LAB_SCENE if lab else SimulationConfig()
    seed = int(rng.integers(1, 1000))
    if args.only and i not in args.only:
        continue
    cfg = replace(cfg, movers=(Mover(drawn[1], 500.0 * 10 ** (db / 20)),))
    path = out / f"m{args.seed}_{i}.h5"
    simulate_capture(path, drawn[0], span[1], seed=seed, config=cfg, start_s=span[0])
    head = f"{i} {kind} start={span[0]:.4f} s span={span[1]:.4f} s other={db:+.1f} dB " \
           f"{'lab' if lab else 'clean'} seed={seed}:"
    try:
        t = process(path, processor=be)
    except FmcwError as e:          # a finding too: the line says it, the others still run
        failed += 1
        print(f"{head} failed: {e}  <<<<", flush=True)
        continue
    with Capture(path) as cap:
        truths = cap.truth_objects()
    scores = object_scores(t, truths)
    bad = sum(s["wrong"] for s in scores)
    best = best_held(scores, len(truths))
    total += bad
    rows = untracked(t, truths)
    apart = [r["apart_held"] for r in rows[:2]]
    at80 += [sum(b >= 0.8 for b in best[:2]), sum(a >= 0.8 for a in apart)]
    print(f"{head} objects {len(t.objects or [])} wrong {bad} best {[round(100 * b) for b in best]} % "
          f"apart {[round(100 * a) for a in apart]} %{'  <<<<' if bad else ''}", flush=True)
    if args.why:
        went += [sum(r[k] * r["periods"] for r in rows) for k in UNTRACKED]
        print("    why", " ".join("/".join(f"{100 * r[k]:.0f}" for k in UNTRACKED) for r in rows), flush=True)
print("valid pairs > 2 mm off their object's truth, all captures:", total)
print("captures that failed to convert:", failed)
print(f"movers at 80 % of their visible periods: {at80[0]}, of those apart (> 2 mm): {at80[1]}")
if args.why and went.sum():
    print("movers' visible periods, all captures:", ", ".join(
        f"{k} {100 * x / went.sum():.1f} %" for k, x in zip(UNTRACKED, went, strict=True)))
