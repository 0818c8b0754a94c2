"""Launcher of kernels/resample.cl (twin: fmcw_cl.stages.resample.resample)."""

from __future__ import annotations

import numpy as np

from ..numeric import median
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl

GPU_LOCAL = 128     # work-items of `resample`'s groups (a half-sweep each)


def codes_of(bufs: Buffers, codes: np.ndarray):
    """A chunk's beat codes on the device, uploaded once for all its launches; the last
    three chunks' stay (a chunk's range check runs after the next one's tracker, whose
    time the one after that is resampled in: ChunkProcessor.process)."""
    return bufs.upload_once("codes", codes if codes.dtype == np.int16 else codes.astype(np.int16), keep=3)


def resample_each(rt: Runtime, bufs: Buffers, codes: np.ndarray, jobs: list, win: np.ndarray,
                  also: tuple = ()) -> list[DeviceRows]:
    """Resampled, mean-removed, windowed half-sweeps of each (starts, lengths, u[, runs])
    of `jobs` (a pair's rising and falling half-sweeps), (S, N) float32 each, left on the
    device (twin: stages.resample.resample): `resample_groups` of one group, the device
    buffers of `also` following the rows in the list returned."""
    rows, extra = resample_groups(rt, bufs, [(codes, jobs, win)], also)
    return rows[0] + extra


def _split(job: tuple) -> list[np.ndarray]:
    """The positions of `job` (starts, lengths, u[, runs]) split for the kernel (see
    kernels/resample.cl): each sweep's integer sample, the fraction past it and its length
    less its run's nominal length (the run's median), the LUT times each nominal length
    in whole samples and fractions (one table a run), and each sweep's run. `runs` counts
    consecutive sweeps whose rows must not depend on the others' (the chunks of one pass
    of the delay's trials); without it, one run."""
    starts, lengths, u = job[:3]
    lengths = np.asarray(lengths, np.float64)
    counts = np.asarray(job[3] if len(job) > 3 else [starts.size], np.int64)
    counts = counts[counts > 0]
    ends = np.cumsum(counts)
    nominal = np.array([median(lengths[e - n: e]) for n, e in zip(counts, ends, strict=True)])
    whole = nominal[:, None] * u
    lut_int = np.floor(whole)
    base = np.floor(starts).astype(np.int32)
    run = np.repeat(np.arange(counts.size, dtype=np.int32), counts if counts.size > 1 else 0)
    return [base, starts - base, lengths - np.repeat(nominal, counts), lut_int.ravel(),
            (whole - lut_int).ravel(), run]


def rows_across(rt: Runtime, lut_int: np.ndarray, points: int) -> tuple[int, int] | None:
    """`resample_rows`' (kernels/resample.cl) first code past each row's base and count of
    codes (a multiple of the lanes) for the LUT's whole samples `lut_int` (one run), or
    None where its local memory (those codes and the rows, as float lanes) exceeds the
    device's: `resample_lanes` then."""
    lo, hi = int(lut_int.min()) - 2, int(lut_int.max()) + 4
    count = -(-(hi - lo + 1) // rt.width) * rt.width
    return (lo, count) if 4 * rt.width * (count + points) <= rt.device.local_mem_size else None


KINDS = (np.int32, np.float32, np.float32, np.int32, np.float32, np.int32)   # `_split`'s arrays on the device


def resample_groups(rt: Runtime, bufs: Buffers, groups: list, also: tuple = (),
                    name: str = "positions") -> tuple[list, list]:
    """`resample_each` of each (codes, jobs, window) of `groups` (a chunk's pairs, a
    chunk's range check), the positions of every job and the arrays `also` (a later
    step's inputs) up by one copy, into the device buffer `name` (a chunk's pairs take
    two by turns, its range check and survey another: OpenCLProcessor.resample_pairs).
    The codes are uploaded once for all launches on one array (`codes_of`).

    Returns the rows of each group's jobs, and the device buffers of `also`."""
    split = [_split(job) for _, jobs, _ in groups for job in jobs]
    values = [x for arrays in split for x in arrays]
    parts = [(kind, x.size) for x, kind in zip(values, KINDS * len(split), strict=True)]
    parts += [(a.dtype, a.size) for a in also]
    buffers = Packed(bufs, name, parts).upload(*values, *also)
    out, i = [], 0
    for codes, jobs, win in groups:
        d_codes = codes_of(bufs, codes)
        d_win = bufs.constant("win", win)
        rows_of = []
        for starts, _, u, *_ in jobs:
            sweeps, points = starts.size, u.size
            rows = DeviceRows(bufs, sweeps, points)
            rows_of.append(rows)
            if sweeps:
                d_base, d_off, d_dlen, d_int, d_frac, d_run = buffers[6 * i: 6 * i + 6]
                runs = split[i][3].size // points                 # LUT tables, one a run
                d_u = bufs.constant("u", u)
                args = (d_codes, d_base, d_off, d_dlen, d_int, d_frac, d_run, np.int32(runs), d_u, d_win,
                        np.int32(points))
                # CPUs: a row a lane, a launch a run (its rows share its LUT table), where local
                # memory holds a run's codes and rows
                tables = split[i][3].reshape(runs, points)
                across = [rows_across(rt, t, points) for t in tables] if rt.lanes else [None]
                if all(a is not None for a in across):
                    counts = np.bincount(split[i][5], minlength=runs) if runs > 1 else np.array([sweeps])
                    ends = np.cumsum(counts)
                    for r, ((lo, count), end, n) in enumerate(zip(across, ends, counts, strict=True)):
                        rt.kernel("resample", "resample_rows")(
                            rt.queue, (-(-int(n) // rt.width),), (1,), d_codes, np.int32(codes.size), d_base,
                            d_off, d_dlen, d_int, d_frac, np.int32(r * points), d_u, d_win, np.int32(points),
                            np.int32(end - n), np.int32(end), rows.buffer, np.int32(lo), np.int32(count),
                            cl.LocalMemory(4 * rt.width * count), cl.LocalMemory(4 * rt.width * points))
                elif rt.lanes:
                    rt.kernel("resample", "resample_lanes")(rt.queue, (sweeps,), (1,), *args, rows.buffer)
                else:
                    rt.kernel("resample", "resample")(rt.queue, (sweeps * GPU_LOCAL,), (GPU_LOCAL,), *args,
                                                      rows.buffer, cl.LocalMemory(4 * GPU_LOCAL))
            i += 1
        out.append(rows_of)
    return out, buffers[6 * i:]
