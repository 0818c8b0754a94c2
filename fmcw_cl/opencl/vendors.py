"""OpenCL runtimes installed by pip, made visible to the ICD loader.

pyopencl's loader (ocl-icd) finds a runtime through an ICD file, a line naming its
library, in /etc/OpenCL/vendors (or the folder OCL_ICD_VENDORS names), besides the PoCL
and Oclgrind bundled with pyopencl. Intel's OpenCL CPU runtime from pip
(`intel-opencl-rt`) ships an ICD file naming its build machine's path, so no loader
finds it, although its library (which finds its own dependencies beside it, RUNPATH
$ORIGIN) works from where pip put it. `register()` writes a vendors folder holding the
system's ICD files and one per pip runtime, naming its library by absolute path, and
points OCL_ICD_VENDORS at it, before the loader first lists platforms. A user's own
OCL_ICD_VENDORS is left as it is: it says which runtimes that user wants.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import os
import tempfile
from pathlib import Path

SYSTEM_VENDORS = Path("/etc/OpenCL/vendors")
# pip distributions that carry an OpenCL runtime no ICD file finds: (distribution, library)
PIP_RUNTIMES = (("intel-opencl-rt", "libintelocl.so"),)
# set on the folders this module writes, so that a child process (a test's CLI, a Dask
# worker) knows the OCL_ICD_VENDORS it inherits is this module's, not the user's
MARK = "FMCW_CL_ICD_VENDORS"


def pip_runtimes() -> dict[str, Path]:
    """{distribution: absolute path of its OpenCL library} of the pip runtimes installed."""
    found = {}
    for dist_name, library in PIP_RUNTIMES:
        try:
            dist = importlib.metadata.distribution(dist_name)
        except importlib.metadata.PackageNotFoundError:
            continue
        for f in dist.files or ():
            if f.name == library:
                path = Path(dist.locate_file(f)).resolve()
                if path.is_file():
                    found[dist_name] = path
                break
    return found


def _system_icds() -> dict[str, str]:
    """{file name: its line} of the system's ICD files."""
    folder = SYSTEM_VENDORS
    if not folder.is_dir():
        return {}
    out = {}
    for f in sorted(folder.glob("*.icd")):
        try:
            out[f.name] = f.read_text(errors="replace").strip()
        except OSError:
            continue
    return out


def cache_dir() -> Path:
    """The user's cache folder of fmcw-cl ($XDG_CACHE_HOME or ~/.cache), or one in the
    temporary folder where the home cannot be written."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "fmcw-cl"
    try:
        base.mkdir(parents=True, exist_ok=True)
        if os.access(base, os.W_OK):
            return base
    except OSError:
        pass
    base = Path(tempfile.gettempdir()) / f"fmcw-cl-{os.getuid()}"
    base.mkdir(parents=True, exist_ok=True)
    return base


def vendors_folder(icds: dict[str, str], base: Path) -> Path:
    """A folder under `base` holding the ICD files `icds` ({name: line}), named by
    their content, so that every process with the same runtimes shares one; written
    beside and renamed, so that no process sees it half written."""
    digest = hashlib.sha1(repr(sorted(icds.items())).encode()).hexdigest()[:16]
    folder = base / f"icd-{digest}"
    if not folder.is_dir():
        tmp = Path(tempfile.mkdtemp(prefix=".icd-", dir=base))
        for name, line in icds.items():
            (tmp / name).write_text(line + "\n")
        try:
            tmp.rename(folder)
        except OSError:             # another process made it first: the same content
            for f in tmp.iterdir():
                f.unlink()
            tmp.rmdir()
    return folder


def register() -> list[str]:
    """Make the pip runtimes visible to the ICD loader (module doc); returns the
    distributions registered (none where the user set OCL_ICD_VENDORS)."""
    ours = os.environ.get(MARK)
    if os.environ.get("OCL_ICD_VENDORS") and os.environ["OCL_ICD_VENDORS"] != ours:
        return []
    runtimes = pip_runtimes()
    if not runtimes:
        return []
    icds = _system_icds()
    named = " ".join(icds.values())
    icds.update({f"pip-{dist}.icd": str(lib) for dist, lib in runtimes.items() if str(lib) not in named})
    try:
        folder = str(vendors_folder(icds, cache_dir()))
    except OSError:
        return []                   # nowhere to write: the loader sees what it sees
    os.environ["OCL_ICD_VENDORS"] = os.environ[MARK] = folder
    return sorted(runtimes)
