"""Progress on long commands: done share, MS/s, multiple of real time, time left.

Shown on stderr only when it is a terminal (and not --quiet), redrawn at most five
times a second.

Kept rather than tqdm or rich: what a user checks here is two rates of one count, the
ADC's MS/s and the multiple of real time (samples / sample rate), and a bar of those
libraries shows one rate unit; the rest (a terminal check, a throttle, time left) is
these few lines, and the command line takes no dependency for it.
"""

from __future__ import annotations

import signal
import sys
import time

_interrupted = False


def _on_sigint(signum, frame) -> None:
    global _interrupted
    _interrupted = True
    raise KeyboardInterrupt


def _unraisable(hook):
    def quiet(unraisable) -> None:
        if not (_interrupted and isinstance(unraisable.exc_value, KeyboardInterrupt)):
            hook(unraisable)
    return quiet


def latch_interrupts() -> None:
    """Make Ctrl-C stick (the command line's main thread). Python raises the
    KeyboardInterrupt at its next bytecode check, and one that lands inside a finalizer
    or a weak reference's callback (device buffers return to their pool that way, right
    after the blocking waits where a conversion spends its time) is printed as ignored
    and lost: the batch ran on (2 Ctrl-C of 6 in a test). The latch raises it again at
    the next safe point (`check_interrupted`) and keeps the lost one from being printed."""
    signal.signal(signal.SIGINT, _on_sigint)
    sys.unraisablehook = _unraisable(sys.unraisablehook)


def check_interrupted() -> None:
    """Raise KeyboardInterrupt if Ctrl-C came since `latch_interrupts`."""
    if _interrupted:
        raise KeyboardInterrupt


class Progress:
    """Progress of one job measured in ADC samples (per channel)."""

    def __init__(self, label: str, total: int = 1, sample_rate_hz: float = 1.0,
                 enabled: bool | None = None, stream=None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.label, self.total, self.fs = label, max(1, total), sample_rate_hz
        self.started = time.perf_counter()
        self._last = 0.0

    def rate(self, done: int) -> tuple[float, float]:
        """(samples per second, multiple of real time) so far."""
        elapsed = max(time.perf_counter() - self.started, 1e-9)
        sps = done / elapsed
        return sps, sps / self.fs

    def __call__(self, done: int, total: int | None = None,
                 sample_rate_hz: float | None = None) -> None:
        check_interrupted()                      # each chunk: a safe point to stop at
        self.total = max(1, total) if total else self.total
        self.fs = sample_rate_hz or self.fs
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self._last < 0.2 and done < self.total:
            return
        self._last = now
        sps, rt = self.rate(done)
        left = (self.total - done) / sps if sps > 0 else float("inf")
        self.stream.write(f"\r{self.label}  {100 * done / self.total:5.1f} %  "
                          f"{sps / 1e6:7.1f} MS/s  {rt:6.2f}x real time  {left:5.1f} s left ")
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\r\033[K")
            self.stream.flush()
