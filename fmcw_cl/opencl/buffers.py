"""Device buffers allocated once per size and reused from chunk to chunk."""

from __future__ import annotations

import numpy as np

from .context import Runtime, cl


class Buffers:
    """Named device buffers that grow when needed and are otherwise reused."""

    def __init__(self, rt: Runtime) -> None:
        self.rt = rt
        self._bufs: dict[str, object] = {}
        self._sizes: dict[str, int] = {}

    def get(self, name: str, nbytes: int):
        nbytes = max(int(nbytes), 4)
        if self._sizes.get(name, 0) < nbytes:
            self._bufs[name] = cl.Buffer(self.rt.context, cl.mem_flags.READ_WRITE, nbytes)
            self._sizes[name] = nbytes
        return self._bufs[name]

    def upload(self, name: str, array: np.ndarray):
        buf = self.get(name, array.nbytes)
        if array.nbytes:
            cl.enqueue_copy(self.rt.queue, buf, np.ascontiguousarray(array))
        return buf
