"""Every OpenCL backend method on small inputs against its numpy twin, on any device:
`python -m fmcw_cl.opencl.selftest DEVICE [GROUP...]` (groups: stream, spectrum,
integrate, survey; all by default), `fmcw-cl devices --check`, benchmarks/gpu.py, and
tests/test_oclgrind.py, which runs one group a process on Oclgrind with its checks on
(where a GPU's work-group sizes are used: Oclgrind claims to be every kind of device).

Every group runs twice, once with each variant of the kernels that have two
(work-groups, a GPU's; float8/int8 lanes, a CPU's: `Runtime.lanes`), whichever the
device uses. Prints one line per method; a mismatch raises SystemExit naming it.
Oclgrind's diagnostics go to its own log (OCLGRIND_LOG), which the test reads.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from fmcw_cl import spectrum_ops
from fmcw_cl.opencl import spectrum as k_spectrum
from fmcw_cl.opencl import track as k_track
from fmcw_cl.opencl import verify as k_verify
from fmcw_cl.opencl.buffers import DeviceRows
from fmcw_cl.opencl.context import cl
from fmcw_cl.opencl.processor import OpenCLProcessor
from fmcw_cl.stages import (
    clutter,
    delay,
    doppler,
    faults,
    integrate,
    lpf,
    pairing,
    resample,
    sync,
    verification,
)
from fmcw_cl.stages.spectrum import Search


def close(name: str, got, want, tol: float) -> None:
    got, want = np.asarray(got, np.float64), np.asarray(want, np.float64)
    if got.shape != want.shape or not np.array_equal(np.isnan(got), np.isnan(want)):
        raise SystemExit(f"{name}: kernel and numpy twin differ (in shape or where they are NaN)")
    known = ~np.isnan(want)
    err = float(np.max(np.abs(got[known] - want[known]), initial=0.0))
    scale = float(np.max(np.abs(want[known]), initial=1.0))
    nans = f", {np.count_nonzero(~known)} NaN alike" if not known.all() else ""
    print(f"{name}: max error {err:.3g} of {scale:.3g}{nans}", flush=True)
    if err > tol * scale:
        raise SystemExit(f"{name}: kernel and numpy twin differ")


GROUPS = ("stream", "spectrum", "integrate", "survey")


def check(selector: str | None, groups: tuple[str, ...] = GROUPS, used_variant: bool = False) -> None:
    """Run the groups of stages on the device `selector` against their twins, with
    both variants of the kernels that have two, or the device's own (`used_variant`)."""
    be = OpenCLProcessor(selector)
    print(f"device: {be.device}, GPU work-groups: {be.rt.group_size(0, 1) == 1}", flush=True)
    for group in groups:
        _group(be, group, (be.rt.lanes,) if used_variant else (False, True))
    print("all kernels match their twins", flush=True)


def _group(be: OpenCLProcessor, group: str, variants: tuple[bool, ...]) -> None:
    rng = np.random.default_rng(0)
    fs, hp = 100e6, 2500.0
    n = 13_337                                               # odd, partial periods
    t = np.arange(n)
    tri = np.abs(((t + 1234) / (2 * hp)) % 1.0 - 0.5) * 2
    sync_codes = (6000 * (tri - 0.5) + rng.normal(0, 4, n)).astype(np.int16)
    beat = (800 * tri + 300 * np.cos(0.21 * t) + rng.normal(0, 50, n)).astype(np.int16)

    chosen = be.rt.lanes
    for lanes in variants:          # of two-variant kernels: work-groups, lanes
        be.rt.lanes = lanes
        print(f"kernel variant: {'lanes' if lanes else 'work-groups'}", flush=True)
        if group == "stream":
            stream(be, beat, sync_codes, fs, hp, np.random.default_rng(1))
        else:
            spectra(be, np.random.default_rng(1), group)
    be.rt.lanes = chosen


def delay_rows(rng, rows: int = 3, n: int = 1237, period: int = 200) -> tuple:
    """Rows of a decimated sync triangle (period `period`) and a beat that is the
    triangle moved by a lag of its own, scaled, with noise, each row's mean removed;
    of two rows or more the last beat row is silent (no triangle: NaN lags). Returns
    (y, z, coarse lags, true lags)."""
    k = np.arange(n, dtype=np.float64)
    z = np.stack([1000 * (np.abs(((k + 31 * r) / period) % 1.0 - 0.5) * 2 - 0.5) for r in range(rows)])
    lag = rng.uniform(-9, 9, rows)
    y = np.stack([0.4 * np.interp(k + a, k, b) for a, b in zip(lag, z, strict=True)])
    y += rng.normal(0, 5, y.shape)
    if rows > 1:
        y[-1] = 0.0
    return y - y.mean(axis=1, keepdims=True), z - z.mean(axis=1, keepdims=True), np.round(lag), lag


def stream(be, beat, sync_codes, fs, hp, rng) -> None:
    """The per-sample stages: low-pass, the sync delay's fit, sync crossings, resampling."""
    y, _, _ = be.intensity(beat, fs)
    close("low-pass (cic_decimate, fir_same)", y, lpf.intensity(beat, fs)[0], 1e-5)
    rows = beat[: 3 * (beat.size // 3)].reshape(3, -1)       # the sync delay's stretches, one launch
    close("low-pass of rows", be.intensity(rows, fs)[0], lpf.intensity(rows, fs)[0], 1e-5)
    y, z, shift, _ = delay_rows(rng)
    got, want = be.fit_periods(y, z, shift, 200, 17), delay.fit_periods(y, z, shift, 200, 17)
    if not all(np.array_equal(np.isnan(g), np.isnan(w)) for g, w in zip(got, want, strict=True)):
        raise SystemExit("sync delay fit (delay_fit): kernel and numpy twin differ in their NaNs")
    ok = np.isfinite(want[0])
    close("sync delay fit (delay_fit)", got[0][ok], want[0][ok], 1e-4)
    close("sync delay fit, misfit", got[1][ok], want[1][ok], 1e-3)
    got = be.period_delays(beat[None], sync_codes[None], fs, hp)      # the codes to the lags, one download
    want = delay.period_delays(beat[None], sync_codes[None], fs, hp)
    if want[0].size == 0 or not np.array_equal(np.isnan(got[0]), np.isnan(want[0])):
        raise SystemExit("sync delay (delay_centre, delay_correlate, delay_coarse): kernels and twin differ")
    ok = np.isfinite(want[0])
    close("sync delay from the codes (delay_centre, delay_correlate, delay_coarse, delay_fit)",
          got[0][ok], want[0][ok], 1e-4)
    got = be.turning_points(sync_codes, hp)
    want = sync.sync_turning_points(sync_codes, hp)
    close("sync (block_sum, sync_levels, span_*, line_fit)", got.time, want.time, 1e-9)

    clipped = beat.copy()
    clipped[[5, 700, beat.size - 1]] = [-8192, 8191, 8190]
    close("clipping counts (clip_blocks)", be.clip_counts(clipped, 256, 8192),
          faults.clip_counts(clipped, 256, 8192), 0)

    points, sweeps = 61, 5                                   # small: the simulator is slow
    u = np.sort(rng.uniform(0, 1, points))
    win = resample.window(points)
    starts = rng.uniform(2, beat.size - 2600, sweeps)
    lengths = np.full(sweeps, 2499.5)
    for uu, way in ((u, "rising u"), (u[::-1], "falling u")):      # a rising current's u falls
        rows = be.resample(beat, starts, lengths, uu, win)
        host = resample.resample(beat, starts, lengths, uu, win)
        close(f"resample, {way}", rows.get(be.rt.queue), host, 1e-5)
        close(f"still echoes out (without_still), {way}", be.without_still(rows, 2).get(be.rt.queue),
              clutter.without_still(host, 2), 1e-3)


def spectra(be, rng, group: str) -> None:
    """The spectrum stages ("spectrum": plain with echoes, de-chirped picked rows, power
    spectra), the integration ("integrate": kept spectra, scattered rows, windows) or
    the echo survey ("survey")."""
    points, nfft, sweeps = 61, 128, 5
    x = rng.normal(0, 100, (sweeps, points))
    x[:, :] += 400 * np.cos(2 * np.pi * 0.2 * np.arange(points))
    d_x = DeviceRows(be.bufs, sweeps, points)
    cl.enqueue_copy(be.rt.queue, d_x.buffer, x.astype(np.float32))
    beta = rng.uniform(-3, 3, points)
    v = rng.uniform(-2, 2, sweeps)
    pick = np.array([4, 1, 2])
    model = doppler.DopplerModel(beta, beta, 0.0, 0.0, 1.0, nfft)
    # the falling rows' tone 0.2 + 0.01 s cycles a point higher: pair s moves
    y = x + 400 * np.cos(2 * np.pi * (0.2 + 0.01 * np.arange(sweeps))[:, None] * np.arange(points))
    d_y = DeviceRows(be.bufs, sweeps, points)
    cl.enqueue_copy(be.rt.queue, d_y.buffer, y.astype(np.float32))
    times = pairing.Times(np.arange(sweeps) * 50e-6, np.arange(sweeps) * 50e-6 + 25e-6)
    if group == "integrate":
        store = be.spectra(d_x, None, None, nfft)
        store = be.spectra(d_x, beta, v[pick], nfft, pick, store)
        want = spectrum_ops.NUMPY.spectra(x, None, None, nfft)
        want = spectrum_ops.NUMPY.spectra(x, beta, v[pick], nfft, pick, want)
        close("kept spectra (scattered rows)", store.get(be.rt.queue), want, 1e-4)
        disp = np.array([0.0, 1.3, -2.7, 70.0, 3.1])
        got = be.integrated_peaks(store, disp, 3, Search(3, nfft // 2))
        want = integrate.peaks(want, disp, 3, Search(3, nfft // 2))
        close("integration (integrate_peak, or integrate_lanes)", got[0], want[0], 1e-4)
        if k_track.supported(be.rt):
            # the passes on integrated spectra, in two groups (the displacement carried
            # over between work-items, restarted at a group's start)
            grouped = replace(times, groups=np.array([0, 2]))
            got = be.integrated((d_x, d_y), grouped, model, Search(3, nfft // 2), 3, 3)
            want = spectrum_ops.SpectrumOps.integrated(be, (d_x, d_y), grouped, model, Search(3, nfft // 2),
                                                       3, 3)
            close("integrated passes (track_start, track_pass: displace)", got.vd, want.vd, 1e-9)
            close("integrated passes, distances", got.d_r, want.d_r, 1e-9)
            close("integrated passes, counts", got.count, want.count, 0)
            close("integrated verdict (track_valid: floors)", got.verdict[0],
                  pairing.verdict(want, grouped, model)[0], 0)
        return
    if group == "survey":
        others = np.full((pick.size, 2), np.nan)
        others[0, 0] = 40.0
        tracked, plain_bin = np.array([25.7, 26.1, 30.0]), np.array([25.2, 27.0, 29.0])
        args = (beta, v[pick], nfft, pick, 3, tracked, plain_bin, others)
        got, want = be.survey(d_x, *args), spectrum_ops.NUMPY.survey(x, *args)
        close("survey (hidden): found", got[2], want[2], 0)
        close("survey (hidden): centroid", got[1], want[1], 1e-4)
        # the ratio divides by the target's energy, a difference of float32 sums: 1e-2
        close("survey (hidden): ratio", got[0], want[0], 1e-2)
        return
    search = Search(3, nfft // 2 - 5, echoes=True)
    got = be.measure(d_x, beta, None, model, search)
    want = doppler.measure(x, beta, None, model, search)
    close("FFT + peak + echoes, bins", got[0], want[0], 1e-4)
    close("FFT + peak + echoes, echo counts", got[2].count, want[2].count, 0)
    got = be.measure(d_x, beta, v[pick], model, Search(3, nfft // 2), pick)
    want = doppler.measure(x, beta, v[pick], model, Search(3, nfft // 2), pick)
    close("de-chirp + FFT + peak, picked rows", got[0], want[0], 1e-4)
    # the range check's 4096-point transform, in the lanes local memory holds (spectrum.lanes_of),
    # where the device holds it at all (else the numpy twin takes it: Oclgrind's 32 KiB)
    if k_spectrum.fits(be.rt, 4096):
        check = replace(model, nfft=4096)
        got = be.measure(d_x, beta, None, check, Search(3, 2000))
        want = doppler.measure(x, beta, None, check, Search(3, 2000))
        close("FFT + peak at 4096 points (the range check)", got[0], want[0], 1e-4)
    # the phase at a fractional peak (phase.cl), de-chirped and plain, both directions
    bins = [rng.uniform(20, 40, sweeps), rng.uniform(20, 40, sweeps)]
    for vel in (v, None):
        got = be.phasors_each((d_x, d_y), (beta, -beta), vel, bins, nfft)
        want = spectrum_ops.NUMPY.phasors_each((x, y), (beta, -beta), vel, bins, nfft)
        for g, w in zip(got, want, strict=True):
            close(f"peak phasor{'' if vel is None else ', de-chirped'} (peak_phasor)",
                  np.stack([g.real, g.imag]), np.stack([w.real, w.imag]), 1e-4)
    if k_track.supported(be.rt):
        # the passes' decisions on the device against the host's, on the same peaks
        got = be.track((d_x, d_y), times, model, search, 3, True)[1]
        want = spectrum_ops.SpectrumOps.track(be, (d_x, d_y), times, model, search, 3, True)[1]
        close("tracker passes (track_pass)", got.vd, want.vd, 1e-9)
        close("tracker passes, distances", got.d_r, want.d_r, 1e-9)
        valid, resid = pairing.verdict(want, times, model)
        close("tracker verdict (track_valid)", got.verdict[0], valid, 0)
        # a residual is infinite with too few valid neighbours: -1 m here
        close("tracker verdict, residuals (track_residual)", *(np.nan_to_num(r, posinf=-1.0)
                                                              for r in (got.verdict[1], resid)), 1e-9)
        # the phasors at the passes' final peaks and velocities, made on the device (this
        # state's velocities reach 1e6 m/s: the device's float32 basis, as the spectra's)
        _, vel, _ = doppler.solve_pair(got.d_r, got.d_f, got.vd, times.half_gap, model)
        bins = [np.nan_to_num(d / model.metres_per_bin) for d in (got.d_r, got.d_f)]
        b32 = beta.astype(np.float32).astype(np.float64)
        want = spectrum_ops.NUMPY.phasors_each((x, y), (b32, b32), np.nan_to_num(vel), bins, nfft)
        for g, w in zip(got.phasors, want, strict=True):
            close("peak phasor at the passes' state (peak_phasor_state)", np.stack([g.real, g.imag]),
                  np.stack([w.real, w.imag]), 1e-4)
        # the verification's tests on a track with an echo 3 mm off for 12 pairs
        track = [np.arange(60) * 50e-6]
        track += [0.1 + 0.5 * track[0] + np.where((track[0] > 1e-3) & (track[0] < 1.6e-3), 3e-3, 0.0),
                  np.full(60, 0.5), np.arange(60) % 7 != 3]
        close("verification (kinematic_drop)", k_verify.disagreed(be.rt, be.bufs, *track),
              verification.disagreed(*track), 0)
        close("verification, residuals (track_residual)", k_verify.residuals(be.rt, be.bufs, *track)[0],
              spectrum_ops.NUMPY.residuals(*track)[0], 1e-9)
    close("power spectra", be.power(d_x, None, None, nfft), doppler.power(x, None, None, nfft), 1e-5)


def timed(selector: str, capture: str) -> None:
    """A device's self-check for the automatic choice (`choice.check` runs it in a child
    process): `check` of the variant the device uses, its lines kept back (a mismatch
    exits non-zero naming it), then the best of four conversions of `capture`, printed
    as JSON ({"seconds": s}; the first builds PoCL's kernels for their local sizes)."""
    from fmcw_cl.engine import process
    from fmcw_cl.options import Options

    with contextlib.redirect_stdout(io.StringIO()):
        check(selector, used_variant=True)
    processor = OpenCLProcessor(selector)
    best = float("inf")
    for _ in range(4):
        t = time.perf_counter()
        process(Path(capture), Options(), processor)
        best = min(best, time.perf_counter() - t)
    print(json.dumps({"seconds": best}))


if __name__ == "__main__":
    check(sys.argv[1], tuple(sys.argv[2:]) or GROUPS)
