"""Device buffers allocated once per size and reused from chunk to chunk, and the
page-locked host memory that a GPU's codes are read into."""

from __future__ import annotations

import functools
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .context import Runtime, cl


class Buffers:
    """Named device buffers that grow when needed and are otherwise reused, and a pool
    of anonymous ones for arrays that stay on the device (`DeviceRows`)."""

    def __init__(self, rt: Runtime) -> None:
        self.rt = rt
        self._bufs: dict[str, object] = {}
        self._sizes: dict[str, int] = {}
        self._sources: dict[str, np.ndarray] = {}
        self._recent: dict[str, list[str]] = {}     # upload_once's buffers of a name, least recent first
        self._free: list[tuple[int, object]] = []
        self._constants: OrderedDict[tuple[str, int], tuple[np.ndarray, object]] = OrderedDict()
        self._claimed: set[str] = set()     # named buffers a Packed holds (`claim`)

    # a chunk's arrays vary by a few percent in size (its count of sync crossings, of
    # half-sweeps): a buffer made for one gets this share more, so that it is made once,
    # not again at each new largest chunk
    ROOM = 1 / 8

    def _new(self, flags, nbytes: int = 0, hostbuf=None):
        buf = cl.Buffer(self.rt.context, flags, nbytes, hostbuf=hostbuf)
        self.rt.hold(buf)
        return buf

    def _roomy(self, nbytes: int) -> int:
        return int(nbytes * (1 + self.ROOM)) // 64 * 64 + 64

    def get(self, name: str, nbytes: int):
        nbytes = max(int(nbytes), 4)
        if self._sizes.get(name, 0) < nbytes:
            self._sizes[name] = self._roomy(nbytes)
            self._bufs[name] = self._new(cl.mem_flags.READ_WRITE, self._sizes[name])
            self._sources.pop(name, None)
        return self._bufs[name]

    def claim(self, name: str, nbytes: int) -> tuple[Claim, object]:
        """A buffer of at least `nbytes` for a Packed: `name`'s, or where a Packed still
        holds that one (a chunk's step beside the next's), `name#1`, `name#2`... Sub-
        buffers of two Packed never share a buffer: NVIDIA's OpenCL crashes the process
        releasing overlapping ones (an H200, 2026-12-04). The claim ends when the
        returned `Claim` goes, which the Packed and each of its sub-buffers hold."""
        k = 0
        while (slot := f"{name}#{k}" if k else name) in self._claimed:
            k += 1
        self._claimed.add(slot)
        return Claim(self._claimed, slot), self.get(slot, nbytes)

    def upload(self, name: str, array: np.ndarray, wait: bool = True):
        """`array` into buffer `name`; without `wait` the copy runs behind the host
        (`Runtime.copy`: the array must not change before the next download)."""
        buf = self.get(name, array.nbytes)
        self._sources.pop(name, None)
        if array.nbytes:
            self.rt.copy(buf, np.ascontiguousarray(array), wait)
        return buf

    def upload_once(self, name: str, array: np.ndarray, keep: int = 1):
        """Like `upload`, but skipped when this very array is one of the last `keep`
        uploaded under `name` (a chunk's codes serve several launches; values that never
        change: `constant`); a new one takes the place of the least recently used.
        Where that is no copy (`Runtime.wraps_host`: PoCL) the buffer wraps the host
        array (CL_MEM_USE_HOST_PTR; not on a simulator, which copies it and checks
        reads as if from device memory). Elsewhere the copy does not wait: the arrays are codes (a
        chunk's, a stretch's), which nothing changes before the download that ends
        their step; in page-locked memory (`page_locked`) a GPU's driver copies them by
        DMA while the host goes on."""
        recent = self._recent.setdefault(name, [f"{name}#{i}" if i else name for i in range(keep)])
        slot = next((n for n in recent if self._sources.get(n) is array), None)
        hit = slot is not None
        slot = slot if hit else recent[0]
        recent.remove(slot)
        recent.append(slot)                 # the most recently used last
        if hit:
            return self._bufs[slot]
        array = np.ascontiguousarray(array)
        if self.rt.wraps_host and array.nbytes:
            self._bufs[slot] = self._new(cl.mem_flags.READ_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=array)
            self._sizes[slot] = 0            # never reused for another array
        else:
            self.upload(slot, array, wait=False)
        self._sources[slot] = array          # held: the buffer may point into it
        return self._bufs[slot]

    CONSTANTS = 32      # device copies of constants kept (a few per plan: LUTs, windows, bases)

    def constant(self, name: str, array: np.ndarray, dtype=np.float32):
        """A device copy of a value that stays the same from launch to launch (a LUT, a
        window, a Doppler basis, a placeholder), uploaded once per host object: the
        object is held, so that its identity keeps meaning the same values. Pass the
        same object (the plan's, or a cached one), not a fresh conversion."""
        key = (name, id(array))
        hit = self._constants.get(key)
        if hit is not None and hit[0] is array:
            self._constants.move_to_end(key)
            return hit[1]
        host = np.ascontiguousarray(array, dtype)
        buf = self._new(cl.mem_flags.READ_ONLY, max(host.nbytes, 4))
        if host.nbytes:
            self.rt.copy(buf, host)
        self._constants[key] = (array, buf)
        if len(self._constants) > self.CONSTANTS:
            self._constants.popitem(last=False)
        return buf

    def lease(self, nbytes: int):
        """A buffer of at least `nbytes` from the pool, the smallest that holds them,
        where it is at most twice their size: a large buffer stays for a large request
        (a chunk's resampled rows), and a small request (the range check's quarter of
        them) makes a buffer of its own once. Give it back with `release`."""
        nbytes = max(int(nbytes), 4)
        fits = [i for i, (size, _) in enumerate(self._free) if nbytes <= size <= 2 * self._roomy(nbytes)]
        if fits:
            return self._free.pop(min(fits, key=lambda i: self._free[i][0]))
        nbytes = self._roomy(nbytes)
        return nbytes, self._new(cl.mem_flags.READ_WRITE, nbytes)

    def release(self, leased) -> None:
        self._free.append(leased)

    def forget_sources(self) -> None:
        """Let go of the host arrays `upload_once` holds and of the buffers over them (a
        capture's codes: a CPU device's buffers are the capture's mapped pages, which
        stay mapped while held). Call with the device's work done."""
        for name in self._sources:
            if self._sizes.get(name) == 0:          # over host memory: made for that array only
                del self._bufs[name], self._sizes[name]
        self._sources.clear()


@functools.lru_cache(maxsize=4)
def page_locked(context) -> Callable[[int], np.ndarray]:
    """An allocator of int16 host arrays in page-locked memory of `context` (a buffer
    made with CL_MEM_ALLOC_HOST_PTR, mapped for good: the array holds it), for
    `fmcw_cl.pool.use`. A GPU's driver copies such memory to the device by DMA while
    the host goes on; pageable memory goes through a staging copy first (NVIDIA's
    OpenCL guide). One allocator per context, so that `pool.use` sees the same one."""
    queue = cl.CommandQueue(context)
    lock = threading.Lock()          # the chunk reader's thread allocates too

    def allocate(samples: int) -> np.ndarray:
        flags = cl.mem_flags.READ_WRITE | cl.mem_flags.ALLOC_HOST_PTR
        with lock:
            try:
                buf = cl.Buffer(context, flags, 2 * max(int(samples), 1))
                array, _ = cl.enqueue_map_buffer(queue, buf, cl.map_flags.READ | cl.map_flags.WRITE, 0,
                                                 (int(samples),), np.int16)
            except cl.Error as exc:       # out of page-locked memory: pool makes a plain one
                raise MemoryError(str(exc)) from None
        return array

    return allocate


class DeviceRows:
    """A (rows, points) float32 array that stays on the device; its buffer returns to
    the pool when the object is dropped."""

    def __init__(self, bufs: Buffers, rows: int, points: int) -> None:
        self.shape = (rows, points)
        self._rt = bufs.rt
        leased = bufs.lease(4 * rows * points)
        self.buffer = leased[1]
        self._finalizer = weakref.finalize(self, bufs.release, leased)

    def get(self, queue=None) -> np.ndarray:
        """A host copy (through the runtime's own queue, which `queue` may name)."""
        out = np.empty(self.shape, np.float32)
        if out.size:
            self._rt.copy(out, self.buffer)
        return out


class Claim:
    """A Packed's hold on its named buffer (`Buffers.claim`), let go when it goes."""

    __slots__ = ("_claimed", "slot")

    def __init__(self, claimed: set[str], slot: str) -> None:
        self._claimed, self.slot = claimed, slot

    def __del__(self) -> None:
        self._claimed.discard(self.slot)


@dataclass
class Rider:
    """A small result that crosses with another step's download instead of by a copy of
    its own: `launch(buffer)` enqueues the kernel that writes its `count` values of
    `dtype` into the buffer it is given; `value` is a host copy after that download
    (None until then, or when the step made none)."""

    dtype: type
    count: int
    launch: Callable
    value: np.ndarray | None = None


class Packed:
    """Small arrays that cross together: one device buffer, each array an aligned
    sub-buffer of it (what a kernel argument takes), moved by a single copy each way.

    `parts` are (dtype, count) in order; `views` are the host arrays after `download`
    (or to fill before `upload`), all in one host block. `riders` (`Rider`) get parts
    after those, are launched at once, and come down with the parts.
    """

    def __init__(self, bufs: Buffers, name: str, parts: list[tuple[type, int]], riders: tuple = ()) -> None:
        self._rt = bufs.rt
        align = max(bufs.rt.device.mem_base_addr_align // 8, 16)
        spans, size = [], 0                                  # (offset, dtype, bytes) of each part
        for dtype, count in [*parts, *((r.dtype, r.count) for r in riders)]:
            nbytes = np.dtype(dtype).itemsize * int(count)
            spans.append((size, np.dtype(dtype), nbytes))
            size += -(-max(nbytes, 4) // align) * align
        self._host = np.empty(size, np.uint8)
        self._claim, self._parent = bufs.claim(name, size)
        views = [self._host[o: o + n].view(d) for o, d, n in spans]
        # sub-buffers of this object's own, not kept from chunk to chunk: kept per layout
        # (a few us a chunk saved), those of two layouts overlapped, and NVIDIA's OpenCL
        # (an H200, 2026-12-04) crashed the process releasing them or their buffer. Each
        # holds the claim: its buffer is no other Packed's while one lives
        buffers = [self._parent.get_sub_region(o, max(n, 4)) for o, _, n in spans]
        for buffer in buffers:
            buffer.claim = self._claim
        self.views, self.buffers = views[: len(parts)], buffers[: len(parts)]
        self._riders = list(zip(riders, views[len(parts):], strict=True))
        for rider, buffer in zip(riders, buffers[len(parts):], strict=True):
            rider.launch(buffer)

    def download(self, meanwhile: Callable[[], None] | None = None) -> list[np.ndarray]:
        """Every part, by one copy (waits for the kernels that wrote them); the riders'
        values too. `meanwhile`: host work run once the copy is queued, before it is
        waited for (what it launches runs after the copy, which does not wait for it)."""
        if meanwhile is None:
            self._rt.copy(self._host, self._parent)
            return self._landed()
        landed = self.download_later()
        meanwhile()
        return landed()

    def download_later(self) -> Callable[[], list[np.ndarray]]:
        """`download`, the copy queued now and waited for by the function returned."""
        event = self._rt.copy(self._host, self._parent, wait=False)

        def landed() -> list[np.ndarray]:
            self._rt.landed(event)
            return self._landed()

        return landed

    def _landed(self) -> list[np.ndarray]:
        for rider, view in self._riders:
            rider.value = view.copy()
        return self.views

    def rider(self) -> Rider:
        """These parts as a `Rider` of another step's download: a copy on the device of
        this buffer into that step's `Packed`, after the kernels that write it
        (kernels/copy.cl); `read` its value."""
        nbytes = self._host.nbytes          # a multiple of the alignment, at least 16
        words = nbytes // 16

        def launch(buffer) -> None:
            rt = self._rt
            rt.kernel("copy", "copy_words")(rt.queue, *rt.items(words), self._parent, np.int32(words), buffer)

        return Rider(np.uint8, nbytes, launch)

    def read(self, raw: np.ndarray) -> list[np.ndarray]:
        """Every part from `raw`, the bytes this object's `rider` brought down; its own
        riders' values too."""
        self._host[...] = raw
        return self._landed()

    def upload(self, *arrays: np.ndarray) -> list:
        """`arrays` into the parts, by one copy; their sub-buffers."""
        for view, a in zip(self.views, arrays, strict=True):
            view[...] = a
        return self.send()

    def send(self) -> list:
        """The parts as their views hold them, up by one copy; their sub-buffers. The
        copy does not wait (the host block is this object's own): change no view after."""
        self._rt.copy(self._parent, self._host, wait=False)
        return self.buffers
