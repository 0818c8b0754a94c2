"""A context and queue on one OpenCL device, its built programs and its traffic.

Programs are built once per context and cached; a failed build saves its log to a file
and says where. Which device: `choice`.
"""

from __future__ import annotations

import copy
import tempfile
import time
import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from ..errors import FmcwError
from .choice import CPU, cl, describe, is_simulator, rank, select_device

POCL = "Portable Computing Language"   # PoCL's platform name
# a wait for a GPU polls its event, asleep between polls, from the first pause doubling
# to the last (NVIDIA's runtime spins in its own wait)
POLL_FIRST_S = 20e-6
POLL_LAST_S = 1e-3
ITEMS_LOCAL = (64, 128)        # local size of one-work-item-per-output launches (CPU, GPU): `Runtime.items`
# LLVM's names of the x86 CPUs with AVX-512, for PoCL's target (its version's "HSTR: ...-CPU")
AVX512_CPUS = ("skylake-avx512", "cascadelake", "cooperlake", "cannonlake", "icelake", "tigerlake",
               "rocketlake", "sapphirerapids", "emeraldrapids", "graniterapids", "diamondrapids",
               "knl", "knm", "znver4", "znver5", "x86-64-v4")


def lanes_width(device) -> int:
    """Lanes of `spectrum_lanes`, `resample_rows` and `hidden_lanes` on `device`: 16 (one
    AVX-512 register a float16) where its preferred float vector is that wide and its
    compiler targets AVX-512, else 8 (wider vectors there change the builtins' ABI: a
    build warning). pip's PoCL (LLVM 14) prefers 16 on a Zen 4, whose AVX-512 it sees,
    but compiles for znver3 (AVX2), where float16 code aborts the process ("Do not know
    how to scalarize"): its version names the CPU it compiles for."""
    if device.preferred_vector_width_float < 16:
        return 8
    target = device.version.partition("HSTR:")[2].strip()
    if target and not any(cpu in target for cpu in AVX512_CPUS):
        return 8
    return 16


@dataclass
class Traffic:
    """What crossed between host and device since the counts were last cleared:
    kernel launches, copies each way and their bytes (a zero-copy wrap of host memory,
    PoCL's, is no copy); `events`, when a list, collects each launch's event (the
    queue profiles them: `busy_seconds`)."""

    launches: int = 0
    uploads: int = 0
    downloads: int = 0
    upload_bytes: int = 0
    download_bytes: int = 0
    events: list | None = None

    def counts(self) -> dict[str, int]:
        """Launches, copies and bytes so far (every counter; not the events)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "events"}

    def busy_seconds(self) -> float:
        """Seconds the device spent in the collected launches (they do not overlap on
        one in-order queue)."""
        return sum(e.profile.end - e.profile.start for e in self.events or ()) * 1e-9


class _Counted:
    """A kernel whose launches are counted. Its scalar arguments' types are declared
    at its first launch (the numpy scalars' dtypes), so that pyopencl packs them
    directly: every argument is set at each launch for about 3 us in all, where
    `set_arg` takes 5 us for each scalar, whose type it probes."""

    def __init__(self, kernel, traffic: Traffic) -> None:
        self.kernel, self.traffic = kernel, traffic
        self.typed = False

    def __call__(self, queue, global_size, local_size, *args):
        self.traffic.launches += 1
        if not self.typed:
            self.kernel.set_scalar_arg_dtypes([a.dtype if isinstance(a, np.generic) else None for a in args])
            self.typed = True
        self.kernel.set_args(*args)
        event = cl.enqueue_nd_range_kernel(queue, self.kernel, global_size, local_size)
        if self.traffic.events is not None:
            self.traffic.events.append(event)
        return event


@dataclass
class Runtime:
    """A context and queue on one device, with its built programs."""

    device: object
    context: object = None
    queue: object = None
    programs: dict = field(default_factory=dict)
    kernels: dict = field(default_factory=dict)
    traffic: Traffic = field(default_factory=Traffic)

    lanes: bool = False   # kernels with explicit float8 lanes where there are two variants
    width: int = 8        # lanes of spectrum_lanes, resample_rows, hidden_lanes (kernels/lanes.cl LANES)
    # whether lane kernels build vectors from other vectors' lanes (lanes.cl SHUFFLES):
    # not on a simulator, whose uninitialised-value check reports every such vector and
    # crashes; there spectrum_lanes gathers its rows a value at a time, the same values
    shuffles: bool = True
    held: list | None = None   # every buffer made, on a simulator: `hold`
    # the events of uploads that do not wait: pyopencl's event of such a copy waits for
    # it when dropped, so they are held until a download or `finish` has waited for them
    in_flight: list = field(default_factory=list)
    polls: bool = False     # a wait polls the event asleep (a GPU's): `wait`

    def __post_init__(self) -> None:
        self.context = cl.Context([self.device])
        # profiled: `fmcw-cl bench` reports the device's busy share (timestamps cost nothing
        # measurable)
        self.queue = self._new_queue()
        # a CPU runs a work-group's work-items as a loop, which PoCL vectorises only where
        # the kernel has no loop of its own (kernels/fft_lanes.cl); GPUs want work-groups
        self.lanes = rank(self.device) == CPU
        self.width = lanes_width(self.device)
        self.held = [] if is_simulator(self.device) else None
        self.shuffles = not is_simulator(self.device)
        self.polls = rank(self.device) != CPU

    def hold(self, buffer) -> None:
        """On a simulator, keep `buffer` as long as this runtime. Oclgrind gives a freed
        buffer's slot to the next buffer made, keeping what its uninitialised-value check
        knew of the old one (its size, which bytes were written): values a kernel stores
        past that size would read back as uninitialised (Oclgrind 19.10; upstream has no
        reset on release either). Held, no slot is reused."""
        if self.held is not None:
            self.held.append(buffer)

    def _new_queue(self):
        return cl.CommandQueue(self.context, properties=cl.command_queue_properties.PROFILING_ENABLE)

    def stream(self) -> Runtime:
        """Another in-order queue on this context for another thread, with its own kernel
        objects (a launch sets a kernel's arguments first: two threads must not share
        one) and counters; the context and the built programs are shared."""
        other = copy.copy(self)
        other.queue, other.kernels, other.traffic = other._new_queue(), {}, Traffic()
        other.in_flight = []
        return other

    @property
    def name(self) -> str:
        return describe(self.device)

    @property
    def fp64(self) -> bool:
        """Whether the device computes in double precision (cl_khr_fp64)."""
        return "cl_khr_fp64" in self.device.extensions

    @property
    def real(self) -> type:
        """The kernels' `real` (kernels/real.cl): double where the device has it."""
        return np.float64 if self.fp64 else np.float32

    @property
    def zero_copy(self) -> bool:
        """Whether the device works in host memory (a real CPU device): the codes are
        read in place, without page-locked staging."""
        return rank(self.device) == CPU

    @property
    def wraps_host(self) -> bool:
        """Whether a buffer made over host memory (CL_MEM_USE_HOST_PTR) is that memory:
        PoCL's on a CPU (0.08 ms a map). Intel's CPU runtime copies host memory that is
        not page-aligned when such a buffer is made (40 ms per 83 MB): a copy into a
        buffer kept from chunk to chunk is faster there (file to track 1.2 -> 1.65x
        real time, 2-core Zen 4)."""
        return self.zero_copy and POCL in self.device.platform.name

    def group_size(self, cpu: int, gpu: int) -> int:
        """A work-group size by device type: PoCL vectorises across work-items and
        measured fastest with small groups; GPUs want many work-items a group."""
        return gpu if self.device.type & cl.device_type.GPU else cpu

    def items(self, n: int) -> tuple[tuple[int], tuple[int]]:
        """Global and local size of a launch of n work-items, for a kernel that ignores
        ids from n on: the local size is fixed per device type (ITEMS_LOCAL). PoCL builds
        a kernel anew for each local size it meets (0.1-0.2 s, cached on disk by size),
        and the one it picks itself follows the global size: every capture of another
        length, and every chunk with another count of sync crossings, paid for builds."""
        lsz = min(self.group_size(*ITEMS_LOCAL), self.device.max_work_group_size)
        return (-(-n // lsz) * lsz,), (lsz,)

    def kernel(self, program: str, name: str, width: int | None = None):
        """Kernel `name` of kernels/<program>.cl (built and retrieved once), its lanes
        `width` (None: `width`'s)."""
        width = width or self.width
        key = (program, name, width, self.shuffles)
        if key not in self.kernels:
            self.kernels[key] = _Counted(cl.Kernel(self.program(program, width), name), self.traffic)
        return self.kernels[key]

    def copy(self, dest, src, wait: bool = True):
        """One copy between a host array and a device buffer (direction by type),
        counted in `traffic`; it waits unless not `wait`. An upload that does not wait
        must not change its array until the queue has read it (its event holds it until
        then; an upload that waits, waits for every launch before it on the in-order
        queue); a download that does not wait returns its event, to wait for before the
        array is read."""
        if isinstance(dest, np.ndarray):
            self.traffic.downloads += 1
            self.traffic.download_bytes += dest.nbytes
            event = cl.enqueue_copy(self.queue, dest, src, is_blocking=False)
            if not wait:             # the caller waits for `event` before it reads `dest`
                return event
            self.wait(event)
            self.in_flight.clear()       # the in-order queue has done every copy before it
        else:
            self.traffic.uploads += 1
            self.traffic.upload_bytes += src.nbytes
            event = cl.enqueue_copy(self.queue, dest, src, is_blocking=False)
            if wait:
                self.wait(event)
            else:
                self.in_flight.append(event)

    def wait(self, event) -> None:
        """Wait for `event`. A GPU's host thread does none of the kernels' work, and
        NVIDIA's runtime spins in its own wait, a core for nothing (a batch's processes on
        one GPU each took one): there the event's status is polled asleep, the pause
        doubling from POLL_FIRST_S to POLL_LAST_S (`polls`). A CPU runtime keeps its own:
        PoCL's sleeps; Intel's runs kernels in the waiting thread (`docs/devices.md`)."""
        if self.polls:
            self.queue.flush()             # submitted, or its status may never change
            pause = POLL_FIRST_S
            while event.command_execution_status > 0:        # queued, submitted, running
                time.sleep(pause)
                pause = min(2 * pause, POLL_LAST_S)
        event.wait()                   # (done: at once; raises where it failed)

    def finish(self) -> None:
        """Wait for everything enqueued."""
        self.wait(cl.enqueue_marker(self.queue))
        self.in_flight.clear()

    def landed(self, event) -> None:
        """Wait for the download of `event` (`copy` without `wait`): every copy before it
        on the in-order queue is done too (uploads queued after it may not be)."""
        self.wait(event)
        done = cl.command_execution_status.COMPLETE
        self.in_flight = [e for e in self.in_flight if e.command_execution_status != done]

    def program(self, name: str, width: int | None = None):
        """kernels/<name>.cl built for this context, lanes `width` (None: `width`'s) and
        `shuffles` (cached)."""
        width = width or self.width
        key = (name, width, self.shuffles)
        if key not in self.programs:
            from fmcw_cl.kernels import files_of, source

            prog = cl.Program(self.context, source(name))
            try:
                with warnings.catch_warnings():
                    # a build log that is not empty: Intel's and NVIDIA's say what they did
                    # (the kernels build without warnings: tests/test_opencl.py, -Werror)
                    warnings.simplefilter("ignore", cl.CompilerWarning)
                    prog.build(options=["-cl-std=CL1.2", f"-DLANES={width}",
                                        f"-DSHUFFLES={int(self.shuffles)}"])
            except cl.Error as exc:
                log = Path(tempfile.gettempdir()) / f"fmcw-cl-{name}-build.log"
                log.write_text(str(exc))
                cl_files = " + ".join(f"{f}.cl" for f in files_of(name))
                raise FmcwError(f"kernel {cl_files} failed to build on {self.name}; "
                                f"build log: {log}") from None
            self.programs[key] = prog
        return self.programs[key]


_RUNTIMES: dict[int, Runtime] = {}


def runtime(selector: str | None = None) -> Runtime:
    """The (cached) runtime of the selected device: one context per device and process."""
    dev = select_device(selector)
    key = dev.int_ptr
    if key not in _RUNTIMES:
        _RUNTIMES[key] = Runtime(dev)
    return _RUNTIMES[key]


