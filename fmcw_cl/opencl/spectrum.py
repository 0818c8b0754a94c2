"""Launcher of kernels/fft.cl + peak.cl + cfar.cl, or of fft_lanes.cl on CPU devices (twins:
fmcw_cl.stages.spectrum.power_spectra, find_peaks, fmcw_cl.stages.cfar.detect and
fmcw_cl.stages.doppler.measure)."""

from __future__ import annotations

import functools

import numpy as np

from ..stages import cfar
from ..stages.spectrum import GUARD_BINS, Peaks
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl


@functools.lru_cache(maxsize=1)
def cfar_scales() -> np.ndarray:
    """stages.cfar.scales(), the same object each time."""
    return cfar.scales()


@functools.lru_cache(maxsize=8)
def zeros(n: int) -> np.ndarray:
    """A zero array of n, the same object each time (a placeholder uploaded once)."""
    out = np.zeros(n)
    out.flags.writeable = False
    return out


@functools.lru_cache(maxsize=8)
def tables(nfft: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Twiddles exp(-2 pi i m / nfft), m < nfft, and where the radix-4 decimation-in-
    frequency transform (radix 2 last when log2(nfft) is odd) leaves bin k < nfft: the
    first stage puts k mod 4 in quarter k mod 4, and so on, the digits of k reversed."""
    m = np.arange(nfft)
    tw = np.exp(-2j * np.pi * m / nfft)
    radices, n = [], nfft
    while n >= 4:
        radices.append(4)
        n //= 4
    if n == 2:
        radices.append(2)
    perm = np.zeros(nfft, np.int64)
    rest, block = m.copy(), nfft
    for r in radices:
        block //= r
        perm += (rest % r) * block
        rest //= r
    return tw.real.astype(np.float32), tw.imag.astype(np.float32), perm.astype(np.int32)


def local_size(rt: Runtime, nfft: int) -> int:
    """Work-group size by device type, at most one work-item per first-stage butterfly.
    On an H100 (2026-11-23), a 1 s capture's FFT + peak + echoes took 3.0 ms with 128
    work-items, 3.1 with 64, 3.5 with 256 and 5.6-5.9 with 512-1024."""
    return min(rt.group_size(16, 128), nfft // 4)


def local_bytes(rt: Runtime, nfft: int) -> int:
    """Local memory one work-group of `spectrum_peak` needs for an nfft-point transform
    (the echoes' flags included)."""
    return 4 * (2 * nfft + nfft // 2) + 12 * local_size(rt, nfft) + nfft // 2


def lanes_bytes(rt: Runtime, nfft: int, width: int | None = None) -> int:
    """Local memory of one work-group of `spectrum_lanes`: the transform and the power
    of its two rows, `width` lanes each (None: `Runtime.width`)."""
    return 3 * nfft * 4 * (width or rt.width)


def lanes_of(rt: Runtime, nfft: int) -> int:
    """The lanes `spectrum_lanes` (fft_lanes.cl) runs an nfft-point transform in: on a
    CPU device (`Runtime.lanes`), `Runtime.width`, or 8 or 4 where its local memory
    holds only those (Intel's CPU runtime, 256 KiB: the 4096-point range check in 4, 3000
    rows in 13-20 ms against `spectrum_peak`'s 76-77); 0: none holds it, `spectrum_peak`
    runs it."""
    if not rt.lanes:
        return 0
    return next((w for w in (rt.width, 8, 4) if w <= rt.width
                 and lanes_bytes(rt, nfft, w) <= rt.device.local_mem_size), 0)


def widths(rt: Runtime) -> set[int]:
    """The lanes `spectrum_lanes` may run in on this device other than `Runtime.width`
    (`lanes_of` up to the 8192 points of the range check at --points 2048): their
    programs are built with the others, before any work."""
    return {lanes_of(rt, 1 << p) for p in range(7, 14)} - {0, rt.width}


def uses_lanes(rt: Runtime, nfft: int) -> bool:
    """Whether `spectrum_lanes` runs an nfft-point transform (`lanes_of`); else
    `spectrum_peak`."""
    return lanes_of(rt, nfft) > 0


def fits(rt: Runtime, nfft: int) -> bool:
    """Whether an nfft-point transform fits in the device's local memory (a GPU's 48 KB
    holds 4096 points, 43.5 KiB at 128 work-items; 8192, the range check at --points
    2048, needs 85.5 KiB: `local_bytes`)."""
    return uses_lanes(rt, nfft) or local_bytes(rt, nfft) <= rt.device.local_mem_size


def measure(rt: Runtime, bufs: Buffers, rows, beta: np.ndarray | None,
            velocity: np.ndarray | None, nfft: int, lo: int, hi: int | None = None,
            keep_power: bool = False, index: np.ndarray | None = None, echoes: bool = False,
            store: DeviceRows | None = None, scatter: bool = True
            ) -> tuple[Peaks | None, np.ndarray | None, cfar.Detections | None]:
    """Peaks of the de-chirped (velocity given) or plain spectra of `rows` (DeviceRows
    or a host array), the power spectra (sweeps, nfft/2) when `keep_power`, and every
    echo of bins [lo, nfft/2) when `echoes`. `index` picks the rows measured, one
    velocity each (none: picked plain rows go through the de-chirp at 0 m/s). A `store`
    keeps the power on the device instead, and nothing comes back (None, None, None):
    in the rows of `index` when `scatter` (all rows when None), else one row per
    measured sweep."""
    return measure_each(rt, bufs, [(rows, beta, store)], velocity, nfft, lo, hi, keep_power, index, echoes,
                        scatter)[0]


def measure_each(rt: Runtime, bufs: Buffers, jobs: list, velocity: np.ndarray | None, nfft: int, lo: int,
                 hi: int | None = None, keep_power: bool = False, index: np.ndarray | None = None,
                 echoes: bool = False, scatter: bool = True, picked: tuple | None = None,
                 out: Packed | None = None, first: int = 0, listed=None, riders: tuple = (),
                 groups: np.ndarray | None = None, d_groups=None, meanwhile=None, bands: tuple | None = None
                 ) -> list[tuple] | None:
    """`measure` of each (rows, beta, store) of `jobs` (rows of one shape: a pair's
    rising and falling half-sweeps) with the same picked rows, velocities and band: the
    picked rows and velocities go up once (`picked`: their device buffers, already up,
    int32 and float32) and every result comes back by one download. With `out` (a
    Packed whose parts from `first` on are `parts`') the results stay there and nothing
    comes back (None: `results` reads them after its download). `listed`: a device int, how
    many of the `picked` rows to de-chirp (at most all rows; the tracker's list of the
    pairs to measure again, kernels/track.cl), `velocity` then unused. `riders`
    (buffers.Rider) come down with the results. `groups`: the first row of each group
    of rows whose plain spectra are taken as if alone (None: one group; `d_groups`: its
    int32 copy on the device, where already up). `meanwhile`: host work run once the
    launches and the download are queued, before it is waited for. `bands`: each job's
    rows' own bands (device buffers of (rows, 2) int32 [lo, hi), `band_buffers`; None:
    [lo, hi) for every row)."""
    up = {id(rows): as_device(bufs, rows) for rows, _, _ in jobs}      # a host array goes up once
    rows_of = [up[id(rows)] for rows, _, _ in jobs]
    sweeps, points = rows_of[0].shape
    indexed = index is not None or listed is not None
    if index is not None:
        sweeps = int(np.size(index))
        if velocity is None:
            velocity = zeros(sweeps)
            jobs = [(rows, zeros(points), store) for rows, _, store in jobs]
    half = nfft // 2
    hi = half if hi is None else hi
    if sweeps == 0:
        return [(Peaks(np.zeros(0), np.zeros(0, np.float32)), np.zeros((0, half), np.float32),
                 cfar.Detections.empty() if echoes else None)] * len(jobs)
    twr, twi, perm = tables(nfft)
    dechirp = velocity is not None or listed is not None
    if picked is not None:
        d_index, d_v = picked
    elif index is not None:        # the rows picked and their velocities: one upload
        picks = [(np.int32, sweeps), (np.float32, sweeps)]
        d_index, d_v = Packed(bufs, "picked", picks).upload(index, velocity)
    else:
        d_index = bufs.constant("index0", zeros(1), np.int32)
        d_v = (bufs.upload("velocity", np.asarray(velocity, np.float32)) if dechirp
               else bufs.constant("v0", zeros(1)))
    m = cfar.MAX_ECHOES
    deferred = out is not None
    if out is None:
        out = Packed(bufs, "measured", parts(jobs, sweeps, nfft, echoes, keep_power), riders)
    counted = (listed, 1) if listed is not None else (bufs.constant("index0", zeros(1), np.int32), 0)
    transforms = sweeps if dechirp else plain_transforms(groups, sweeps)
    if groups is None:
        d_groups = bufs.constant("index0", zeros(1), np.int32)
    elif d_groups is None:
        d_groups = bufs.upload("groups", np.asarray(groups, np.int32))
    # each job's own buffers: rows, Doppler basis, peak, SNR, power, echoes (bin, SNR, count)
    own = []
    none = bufs.constant("index0", zeros(1), np.int32)
    for i, (rows, (_, beta, store)) in enumerate(zip(rows_of, jobs, strict=True)):
        d_bin, d_snr, d_ebin, d_esnr, d_ecount, d_own = out.buffers[first + 6 * i: first + 6 * i + 6]
        own.append((rows.buffer, bufs.constant("beta", beta if dechirp else zeros(points)),
                    none if bands is None else bands[i], d_bin, d_snr,
                    store.buffer if store is not None else d_own, d_ebin, d_esnr, d_ecount))
    # two consecutive jobs that differ only in those buffers (a pair's rising and falling
    # half-sweeps) go in one launch, a job a row of work-groups: half the launches of the
    # tracker's passes
    stored = [store is not None for _, _, store in jobs]
    launches, i = [], 0
    while i < len(jobs):
        two = i + 1 < len(jobs) and stored[i] == stored[i + 1]
        launches.append([i, i + 1] if two else [i])
        i += 2 if two else 1
    lanes = lanes_of(rt, nfft)
    if lanes:
        items = -(-transforms // lanes)
        items = items if listed is None else min(items, counted_groups(rt))
        local = [cl.LocalMemory(4 * lanes * nfft)] * 3
    else:
        lsz = local_size(rt, nfft)
        items = transforms if listed is None else min(transforms, counted_groups(rt))
        local = [cl.LocalMemory(4 * nfft), cl.LocalMemory(4 * nfft), cl.LocalMemory(4 * half),
                 cl.LocalMemory(12 * lsz), cl.LocalMemory(half if echoes else 1)]
    for group in launches:
        (x, beta, d_band, d_bin, d_snr, d_power, d_ebin, d_esnr, d_ecount) = own[group[0]]
        second = own[group[-1]]
        kept = stored[group[0]]
        args = (x, np.int32(sweeps), np.int32(points), d_index, np.int32(indexed), beta, d_v,
                np.int32(dechirp), bufs.constant("tw_re", twr), bufs.constant("tw_im", twi),
                bufs.constant("perm", perm, np.int32), np.int32(nfft), np.int32(lo), np.int32(hi), d_band,
                np.int32(bands is not None), np.int32(GUARD_BINS), d_bin, d_snr, d_power,
                np.int32(keep_power or kept),
                np.int32(kept and indexed and scatter),
                np.int32(echoes), np.int32(cfar.GUARD), np.int32(cfar.TRAIN),
                bufs.constant("cfar_scale", cfar_scales()), np.int32(m),
                d_ebin, d_esnr, d_ecount, counted[0], np.int32(counted[1]), d_groups,
                np.int32(0 if groups is None else np.size(groups)), np.int32(transforms), *second)
        if lanes:
            rt.kernel("spectrum", "spectrum_lanes", lanes)(rt.queue, (items, len(group)), (1, 1), *args,
                                                           *local)
        else:
            rt.kernel("spectrum", "spectrum_peak")(rt.queue, (items * lsz, len(group)), (lsz, 1), *args,
                                                   *local)
    if deferred:
        return None
    if all(store is not None for _, _, store in jobs):      # the spectra stay for the next kernel
        return [(None, None, None)] * len(jobs)
    return results(out.download(meanwhile), jobs, sweeps, nfft, echoes, keep_power)


def band_buffers(bufs: Buffers, search, directions: tuple = (0, 1)) -> tuple | None:
    """The device copies of `search`'s bands of `directions` (Search.bands, each
    (pairs, 2) int32), by one upload; None where the search has none."""
    if search.bands is None:
        return None
    own = [np.ascontiguousarray(search.bands[j], np.int32).ravel() for j in directions]
    return tuple(Packed(bufs, "bands", [(np.int32, a.size) for a in own]).upload(*own))


def plain_transforms(groups: np.ndarray | None, sweeps: int) -> int:
    """Transforms of `sweeps` plain rows, two to a transform within each group (first
    rows `groups`, None: one group), a group's odd last row alone (kernels/fft.cl)."""
    if groups is None:
        return (sweeps + 1) // 2
    return int(np.sum((np.diff(np.append(groups, sweeps)) + 1) // 2))


GROUPS_PER_UNIT = 8   # groups a compute unit of a counted launch (each loops over its share)


def counted_groups(rt: Runtime) -> int:
    """Work-groups of a launch whose count of rows the device holds (`listed`): each
    takes every so-many-th transform, so that however few are listed they spread over
    every compute unit (one group per block, the listed rows at the front of a launch
    over all rows, measured 1.9x slower on PoCL's two threads: as if one held them all)."""
    return GROUPS_PER_UNIT * rt.device.max_compute_units


def parts(jobs: list, sweeps: int, nfft: int, echoes: bool = False, keep_power: bool = False) -> list:
    """The (dtype, count) of what `measure_each` of `jobs` writes, in order: each job's
    peaks, echoes, and power when kept on the host."""
    echo_rows = sweeps if echoes else 0
    m = cfar.MAX_ECHOES
    out = []
    for _, _, store in jobs:
        own = keep_power and store is None
        out += [(np.float32, sweeps), (np.float32, sweeps), (np.float32, echo_rows * m),
                (np.float32, echo_rows * m), (np.int32, echo_rows),
                (np.float32, sweeps * nfft // 2 if own else 1)]
    return out


def results(views: list, jobs: list, sweeps: int, nfft: int, echoes: bool = False,
            keep_power: bool = False) -> list[tuple]:
    """`measure_each`'s results from the host views of its `parts`."""
    m, half = cfar.MAX_ECHOES, nfft // 2
    got = []
    for i, (_, _, store) in enumerate(jobs):
        b, s, ebin, esnr, ecount, own = views[6 * i: 6 * i + 6]
        power = own.reshape(sweeps, half).copy() if keep_power and store is None else None
        det = None
        if echoes:
            det = cfar.Detections(ebin.reshape(sweeps, m).astype(np.float64), esnr.reshape(sweeps, m).copy(),
                                  ecount.copy())
        got.append((Peaks(b.astype(np.float64), s.copy()), power, det))
    return got


def as_device(bufs: Buffers, rows) -> DeviceRows:
    """`rows` as DeviceRows (a host array is copied up)."""
    if isinstance(rows, DeviceRows):
        return rows
    host = np.ascontiguousarray(rows, np.float32)
    out = DeviceRows(bufs, *host.shape)
    if host.size:
        bufs.rt.copy(out.buffer, host)
    return out
