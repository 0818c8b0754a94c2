"""Writing a capture file (contract section 1) chunk by chunk, under its name only once
complete (`CaptureWriter`).
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from .atomic import atomic_path
from .capture_format import FORMAT, FORMAT_VERSION, TRUTH_FIELDS, Modulation, Truth


class CaptureWriter:
    """Write a capture chunk by chunk; the file appears under its name only when closed.

    Parameters
    ----------
    path : path-like
        Destination file.
    samples : int
        Total samples per channel (the datasets are created at full size).
    sample_rate_hz, bits, modulation :
        ADC and modulation description (contract section 1).
    tuning_current_a, tuning_frequency_hz : array_like
        The offline G(I) table (A, absolute Hz).
    refractive_index : float, optional
        Written to /optics when not None.
    compression : str, optional
        HDF5 filter for the ADC channels ("gzip" for small sample files, in chunks of
        1 Mi samples). None stores each channel in one run of the file, which a CPU's
        processor reads in place (`Capture` `in_place`).
    """

    def __init__(self, path, samples: int, sample_rate_hz: float, bits: int, modulation: Modulation,
                 tuning_current_a, tuning_frequency_hz, refractive_index: float | None = None,
                 compression: str | None = None, attrs: dict | None = None) -> None:
        self.path = Path(path)
        self._atomic = atomic_path(self.path)
        tmp = self._atomic.__enter__()
        try:
            self._file = h5py.File(tmp, "w")
            f = self._file
            f.attrs["fmcw_format"] = FORMAT
            f.attrs["format_version"] = FORMAT_VERSION
            for k, v in (attrs or {}).items():
                f.attrs[k] = v
            adc = f.create_group("adc")
            adc.attrs["sample_rate_hz"] = float(sample_rate_hz)
            adc.attrs["bits"] = int(bits)
            opts = {"compression": compression, "shuffle": True, "chunks": (min(samples, 1 << 20),)} \
                if compression else {}
            self.beat = adc.create_dataset("beat", (samples,), np.int16, **opts)
            self.sync = adc.create_dataset("sync", (samples,), np.int16, **opts)
            mod = f.create_group("modulation")
            mod.attrs["waveform"] = modulation.waveform
            mod.attrs["frequency_hz"] = float(modulation.frequency_hz)
            mod.attrs["current_min_a"] = float(modulation.current_min_a)
            mod.attrs["current_max_a"] = float(modulation.current_max_a)
            laser = f.create_group("laser")
            laser.create_dataset("tuning_current_a", data=np.asarray(tuning_current_a, np.float64))
            laser.create_dataset("tuning_frequency_hz", data=np.asarray(tuning_frequency_hz, np.float64))
            if refractive_index is not None:
                f.create_group("optics").attrs["refractive_index"] = float(refractive_index)
        except BaseException as exc:
            self._abort(exc)
            raise

    def set_bits(self, bits: int) -> None:
        """The ADC's resolution, where it is known only once the codes are written."""
        self._file["adc"].attrs["bits"] = int(bits)

    def write(self, start: int, beat: np.ndarray, sync: np.ndarray) -> None:
        """Store samples [start, start + len) of both channels."""
        self.beat[start:start + beat.size] = beat
        self.sync[start:start + sync.size] = sync

    def write_truth(self, truth: Truth, others: tuple[Truth, ...] = ()) -> None:
        """The target's `truth` in /truth, the scene's other echoes' in /truth/objects/<k>."""
        g = self._file.require_group("truth")
        for t, where in [(truth, g)] + [(o, g.create_group(f"objects/{k}")) for k, o in enumerate(others, 1)]:
            for name in TRUTH_FIELDS:
                where.create_dataset(name, data=np.asarray(getattr(t, name), np.float64))
            if t.visible is not None:
                where.create_dataset("visible", data=np.asarray(t.visible, bool))
            if where is not g:
                where.attrs["kind"] = t.kind

    def _abort(self, exc: BaseException) -> None:
        f = getattr(self, "_file", None)
        if f is not None:
            f.close()
        self._atomic.__exit__(type(exc), exc, exc.__traceback__)

    def close(self) -> None:
        self._file.close()
        self._atomic.__exit__(None, None, None)

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc is None:
            self.close()
        else:
            self._abort(exc)
