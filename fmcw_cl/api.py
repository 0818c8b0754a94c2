"""The Python API: what `fmcw-cl` does, as plain functions (the command line calls these).

>>> import fmcw_cl
>>> track = fmcw_cl.process("data_samples/static_0p3m.h5", backend="numpy")
>>> track.to_pandas().head()                      # doctest: +SKIP

Option names and defaults are the command line's (`fmcw_cl.options`): `--max-range 0.4`
is `max_range=0.4`, `--no-dechirp` is `dechirp=False`.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from pathlib import Path

from . import options as opts
from .capture import Capture
from .track import Track, read_track, write_track

PathLike = str | os.PathLike
MIN_DURATION_S = 1e-4     # `simulate`: two modulation periods

__all__ = ["process", "read_track", "write_track", "open_capture", "simulate", "calibrate", "Track"]


def process(path: PathLike, *, progress: Callable[[int, int, float], None] | None = None,
            warn: Callable[[str], None] | None = None, **options) -> Track:
    """Convert one capture into a track (not written; see `write_track`).

    Parameters
    ----------
    path : the capture file (HDF5, the contract's layout).
    progress : callable(samples_done, samples_total, sample_rate_hz), optional.
    warn : callable(message) for a fallback to numpy (default: warnings.warn).
    **options : those of `fmcw-cl process`, by the same names and defaults:
        points (1000), min_range (0.03 m), max_range (None, m), dechirp (True),
        range_check (True), chirp (None: a calibration file), backend ("auto",
        "opencl", "numpy"), device (None: OpenCL device selector).

    Returns
    -------
    Track : per half-sweep and per pair (distance m, velocity m/s, acceleration m/s^2,
        valid, reason), every echo (`track.echoes`), the parameters (`track.attrs`).
    """
    from .engine import process as run

    config, processor = _configured(options, warn)
    return run(Path(path), config, processor, progress)


def process_each(paths, *, progress: Callable[[int, int, int, float], None] | None = None,
                 warn: Callable[[str], None] | None = None, workers: int | None = None, **options):
    """Convert captures as `fmcw-cl process` does: several at once where the backend
    gains by it (numpy; a GPU), the results in the order of `paths`.

    Parameters
    ----------
    paths : the capture files.
    progress : callable(index, samples_done, samples_total, sample_rate_hz), optional.
    warn, **options : as for `process`.
    workers : captures at once (None: the backend's choice; see batch.process_each).

    Yields
    ------
    (path, Track), or (path, FmcwError) for a capture that cannot be converted.
    """
    from .batch import process_each as run

    config, processor = _configured(options, warn)
    yield from run(paths, config, processor, workers, progress)


def _configured(keywords: dict, warn):
    """The validated Options of `keywords` and the chunk processor they name."""
    from .backend import make_processor
    config, backend, device = opts.from_keywords(keywords)
    return config, make_processor(backend, device, warn=warn or (lambda m: warnings.warn(m, stacklevel=4)))


def open_capture(path: PathLike) -> Capture:
    """The capture file, validated (a context manager; `.info`, `.read(a, b)`, `.truth()`)."""
    return Capture(path)


def simulate(path: PathLike, scenario: str = "jump", *, duration: float | None = None, seed: int = 0,
             distance: float | None = None, start: float = 0.0, noise: float | None = None,
             snr_db: float | None = None, reflectors: tuple[tuple[float, float], ...] = (),
             speckle_ms: float = 0.0, table_noise_mhz: float | None = None, rin_db_hz: float | None = None,
             sync_delay: float | None = None, thermal_lag_us: float = 0.0, compress: bool = False,
             lab: bool = False, no_headroom: bool = False, overwrite: bool = False,
             amplitude_um: float | None = None, frequency_hz: float | None = None,
             speed_mmps: float | None = None,
             progress: Callable[[int, int], None] | None = None) -> dict:
    """Write a simulated capture with `/truth` (the options of `fmcw-cl simulate`).

    Parameters
    ----------
    path : the capture file to write.
    scenario : "static", "rail", "jump", "vibration" or "creep".
    duration : seconds of capture (default: static 0.05, rail 0.4, jump 0.3, vibration
        0.1, creep 0.2).
    seed : seed of every random draw.
    distance : static, vibration, creep: the target's distance (m, 0.3); jump: the
        ground's (m, 0.07).
    start : scenario time (s) at the first sample.
    noise, snr_db : beat noise in rms codes (25), or set by the target's per-sample SNR
        at 0.3 m (dB); not both.
    reflectors : static echoes, (distance m, amplitude codes) each.
    speckle_ms : speckle fading of the target's echo, correlation time (ms; 0: none).
    table_noise_mhz : rms scatter of the G(I) table (MHz, 5).
    rin_db_hz : the laser's relative intensity noise (dB/Hz; None: none).
    sync_delay : samples the sync lags the optics (None: drawn from the seed).
    thermal_lag_us : first-order lag of the thermal part of the tuning (us).
    compress : gzip the ADC channels.
    lab : a lab's instrument (simulator.LAB): an intensity triangle of +-150 codes under
        600 codes rms of noise, a G(I) table with 20 MHz scatter; `noise`, `snr_db` and
        `table_noise_mhz` still apply over it.
    no_headroom : no gain setting: the noise's peaks reach full scale where its rms is
        near it (3000 codes rms on 14 bits: 0.7 % of the codes).
    overwrite : replace `path` where it exists (else that is refused).
    amplitude_um, frequency_hz : vibration: its amplitude (um, 50) and frequency (Hz, 1000).
    speed_mmps : creep: its speed (mm/s, 1).

    Returns
    -------
    dict : the hidden draws (sync delay, start phase).
    """
    from dataclasses import replace

    from .errors import FmcwError
    from .simulator import DURATIONS_S, LAB, SCENARIOS, SimulationConfig, simulate_capture

    if scenario not in SCENARIOS:
        raise FmcwError(f"scenario {scenario!r} is not one of {', '.join(sorted(SCENARIOS))}")
    duration = DURATIONS_S[scenario] if duration is None else duration
    if not duration >= MIN_DURATION_S:
        raise FmcwError(f"{opts.said('duration', duration)} s: a capture lasts at least {MIN_DURATION_S:g} s "
                        "(two modulation periods)")
    for name, value in (("seed", seed), ("start", start), ("noise", noise), ("speckle_ms", speckle_ms),
                        ("table_noise_mhz", table_noise_mhz), ("thermal_lag_us", thermal_lag_us)):
        if value is not None and not value >= 0:
            raise FmcwError(f"{opts.said(name, value)} must be 0 or more")
    if distance is not None and not distance > 0:
        raise FmcwError(f"{opts.said('distance', distance)} m must be more than 0")
    if Path(path).exists() and not overwrite:
        how = opts.said("overwrite") if opts.flags_said() else "overwrite=True"
        raise FmcwError(f"{path}: exists ({Path(path).stat().st_size / 1e6:.1f} MB); name a new file, or "
                        f"replace it with {how}")
    kwargs = {}
    if distance is not None:
        if scenario == "rail":
            raise FmcwError("the rail has no distance option")
        kwargs = {"ground_m" if scenario == "jump" else "distance": distance}
    for name, value, scale, own in (("amplitude_um", amplitude_um, 1e-6, "vibration"),
                                    ("frequency_hz", frequency_hz, 1.0, "vibration"),
                                    ("speed_mmps", speed_mmps, 1e-3, "creep")):
        if value is None:
            continue
        if scenario != own:
            raise FmcwError(f"{opts.said(name, value)}: only the {own} scenario has it")
        if not value > 0:
            raise FmcwError(f"{opts.said(name, value)} must be more than 0")
        kwargs[{"amplitude_um": "amplitude_m", "speed_mmps": "speed_mps"}.get(name, name)] = value * scale
    for d, a in reflectors:
        if d <= 0 or a < 0:
            raise FmcwError(f"reflector {d:g}:{a:g}: the distance must be > 0 m and the amplitude >= 0")
    if noise is not None and snr_db is not None:
        raise FmcwError("give noise or snr_db, not both")
    cfg = replace(LAB if lab else SimulationConfig(), reflectors=tuple(reflectors),
                  speckle_s=speckle_ms * 1e-3, snr_db=snr_db, rin_db_hz=rin_db_hz,
                  thermal_lag_s=thermal_lag_us * 1e-6, sync_delay_samples=sync_delay,
                  headroom=None if no_headroom else LAB.headroom)
    if noise is not None:
        cfg = replace(cfg, noise_codes=noise)
    if table_noise_mhz is not None:
        cfg = replace(cfg, table_noise_hz=table_noise_mhz * 1e6)
    trajectory = SCENARIOS[scenario](duration + start, **kwargs)
    return simulate_capture(path, trajectory, duration, seed, cfg, start_s=start,
                            compression="gzip" if compress else None, progress=progress)


def calibrate(path: PathLike, distance: float, output: PathLike | None = None, *, periods: int = 2000,
              backend: str = "auto", device: str | None = None, warn: Callable[[str], None] | None = None):
    """The laser's real (dynamic) chirp from a capture of a static target at `distance`
    metres (`fmcw-cl calibrate`); written to `output` when given (use it as
    `process(..., chirp=output)`). `backend` and `device` choose the processor of the
    sync delay's trial conversions, as `process`'s do. Returns the Chirp."""
    from .calibration import measure_chirp
    from .chirp import write_chirp

    _, processor = _configured({"backend": backend, "device": device}, warn)
    chirp = measure_chirp(path, distance, periods, processor)
    if output is not None:
        write_chirp(output, chirp)
    return chirp
