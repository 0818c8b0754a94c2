"""Which OpenCL device runs the pipeline.

A device is chosen deliberately, never "whatever comes first": by index "P" or "P:D",
by a substring of the platform or device name, or by the standard PYOPENCL_CTX; else
automatically. The automatic choice takes a GPU, else a CPU, else another device,
never a simulator such as Oclgrind (it claims to be every kind of device); of the
devices of that kind, the fastest of those that pass the self-check. The check runs in
a child process, a device at a time (a runtime whose compiler aborts on a kernel, as
pip's PoCL does on float16 code for a CPU newer than its LLVM, must not take the caller
with it): every kernel against its numpy twin (`selftest`, the variant the device
uses), then a conversion of a short simulated capture, timed. Verdicts are kept in the
user's cache folder (`vendors.cache_dir`), one set per machine's devices, fmcw-cl
version and kernel sources, so the check runs once: a new runtime, driver or kernel
makes a new set.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

from ..errors import FmcwError
from . import vendors

vendors.register()   # before the loader first lists platforms: Intel's CPU runtime from pip

try:  # pyopencl is a dependency, but a broken OpenCL install must not break numpy use
    import pyopencl as cl
except Exception:  # noqa: BLE001 - any import failure means: no OpenCL here
    cl = None

GPU, CPU, OTHER, SIMULATOR = range(4)
KINDS = {GPU: "GPU", CPU: "CPU", OTHER: "other"}
SIMULATORS = ("oclgrind",)     # kernel checkers: they claim every device type
CHECK_SECONDS = 300            # a device whose check takes longer fails it
REFERENCE_S = 0.2              # the timed conversion's capture (a static target at a lab's SNR, 80 MB)


def devices() -> list[tuple[int, int, object, object]]:
    """All (platform index, device index, platform, device) seen."""
    if cl is None:
        raise FmcwError("pyopencl cannot be imported: pip install pyopencl pocl-binary-distribution")
    try:
        platforms = cl.get_platforms()
    except cl.Error:
        return []
    out = []
    for p, plat in enumerate(platforms):
        try:
            devs = plat.get_devices()
        except cl.Error:
            continue
        out.extend((p, d, plat, dev) for d, dev in enumerate(devs))
    return out


def describe(device) -> str:
    return f"{device.platform.name.strip()} / {device.name.strip()}"


def is_simulator(device) -> bool:
    return any(name in f"{device.platform.name} {device.name}".lower() for name in SIMULATORS)


def rank(device) -> int:
    """The automatic choice's order: GPUs, then CPUs, then anything else; a simulator
    (Oclgrind, which runs kernels 1000x slower to check them) never."""
    if is_simulator(device):
        return SIMULATOR
    if device.type & cl.device_type.GPU:
        return GPU
    return CPU if device.type & cl.device_type.CPU else OTHER


def select_device(selector: str | None = None, say=None):
    """The OpenCL device named by `selector`, or chosen automatically (module doc);
    `say(line)` is told of a check that runs (default: stderr)."""
    seen = devices()
    if not seen:
        raise FmcwError("no OpenCL device found: pip install pocl-binary-distribution "
                        "(a CPU OpenCL), or install your GPU vendor's OpenCL driver")
    selector = selector if selector is not None else os.environ.get("PYOPENCL_CTX")
    if selector:
        return _named(seen, selector)
    runnable = [item for item in seen if rank(item[3]) != SIMULATOR]
    if not runnable:
        raise FmcwError(f"only a simulator ({describe(seen[0][3])}) is seen: it checks kernels, "
                        "it does not run them at speed; select it by name (--device) or install an "
                        "OpenCL runtime (pip install pocl-binary-distribution intel-opencl-rt)")
    failed = []
    for kind in (GPU, CPU, OTHER):
        items = [item for item in runnable if rank(item[3]) == kind]
        if not items:
            continue
        found = verdicts(items, say)
        passing = [(v.seconds, i) for i, v in enumerate(found) if v.passed]
        if passing:
            return items[min(passing)[1]][3]
        failed += [f"{describe(item[3])}: {v.why}" for item, v in zip(items, found, strict=True)]
    raise FmcwError(f"no OpenCL device passes the self-check ({'; '.join(failed)}); `fmcw-cl devices "
                    "--device NAME --check` shows a device's check, --device NAME uses it anyway")


def _named(seen, selector: str):
    parts = selector.split(":")
    if all(x.isdigit() for x in parts if x):
        p = int(parts[0])
        d = int(parts[1]) if len(parts) > 1 and parts[1] else 0
        for pi, di, _, dev in seen:
            if (pi, di) == (p, d):
                return dev
        raise FmcwError(f"no OpenCL device {selector!r}; `fmcw-cl devices` lists them")
    for _, _, plat, dev in seen:
        if selector.lower() in f"{plat.name} {dev.name}".lower():
            return dev
    raise FmcwError(f"no OpenCL device matches {selector!r}; `fmcw-cl devices` lists them")


PROBE = "__kernel void probe(__global float *x) { x[get_global_id(0)] *= 2.0f; }"
_PROBED: dict[int, str | None] = {}


def cannot_compile(device) -> str | None:
    """Why `device` cannot build a kernel (the build log's first error line), or None
    when it can; probed once per device and process."""
    key = device.int_ptr
    if key not in _PROBED:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", cl.CompilerWarning)     # Intel's log says what it did
                cl.Program(cl.Context([device]), PROBE).build()
            _PROBED[key] = None
        except cl.Error as exc:
            lines = [x.strip() for x in str(exc).splitlines() if "error" in x.lower() and ":" in x]
            _PROBED[key] = lines[-1] if lines else str(exc).splitlines()[0]
    return _PROBED[key]


@dataclass
class Verdict:
    """A device's self-check: whether it passed, why not, and the seconds of the timed
    conversion (the best of four) where it passed."""

    passed: bool
    why: str = ""
    seconds: float = float("inf")

    def __str__(self) -> str:
        return f"passed, reference {self.seconds:.3f} s" if self.passed else f"failed: {self.why}"


def identity(device) -> str:
    """What makes a device's verdict: its runtime, version, driver and name."""
    plat = device.platform
    return " | ".join(x.strip() for x in (plat.name, plat.version, device.name, device.version,
                                          device.driver_version))


def _set_key(items) -> str:
    """The key of a set of devices' verdicts: their identities, fmcw-cl's version and
    its kernels' sources."""
    from fmcw_cl import __version__
    from fmcw_cl.kernels import sources_digest

    text = "\n".join([__version__, sources_digest(), *sorted(identity(item[3]) for item in items)])
    return hashlib.sha1(text.encode()).hexdigest()[:16]


KEEP_SETS = 16      # sets of verdicts kept in the cache file


def verdicts(items, say=None) -> list[Verdict]:
    """The verdicts of `items` ((platform, device, _, device) as `devices` lists them),
    from the cache, else checked now, each in a child process, and kept."""
    base = vendors.cache_dir()
    key = _set_key(items)
    with open(base / "devices.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)     # one process checks; the others wait for its verdicts
        store = _load(base / "devices.json")
        if key in store:
            return [Verdict(**v) for v in store[key]["verdicts"]]
        say = say or (lambda line: print(line, file=sys.stderr, flush=True))
        say(f"checking {len(items)} OpenCL {KINDS[rank(items[0][3])]} device(s), once for this machine "
            "(every kernel against numpy, a timed conversion) ...")
        with tempfile.TemporaryDirectory(dir=base) as tmp:
            capture = _reference(Path(tmp) / "reference.h5")
            found = []
            for p, d, _, dev in items:
                found.append(check(f"{p}:{d}", dev, capture))
                say(f"  {describe(dev)}: {found[-1]}")
        store[key] = {"devices": [identity(item[3]) for item in items],
                      "verdicts": [asdict(v) for v in found], "made": time.time()}
        for old in sorted(store, key=lambda k: store[k]["made"])[:-KEEP_SETS]:
            del store[old]
        _save(base / "devices.json", store)
        return found


def cached(device) -> Verdict | None:
    """The verdict kept for `device` in any set, the newest (None: never checked)."""
    store = _load(vendors.cache_dir() / "devices.json")
    name = identity(device)
    for entry in sorted(store.values(), key=lambda e: -e["made"]):
        if name in entry["devices"]:
            return Verdict(**entry["verdicts"][entry["devices"].index(name)])
    return None


def check(selector: str, device, capture: Path) -> Verdict:
    """`device`'s self-check in a child process (module doc)."""
    why = cannot_compile(device)
    if why is not None:
        return Verdict(False, f"cannot compile: {why}")
    try:
        child = f"from fmcw_cl.opencl.selftest import timed; timed({selector!r}, {str(capture)!r})"
        proc = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True,
                              timeout=CHECK_SECONDS)
    except subprocess.TimeoutExpired:
        return Verdict(False, f"the check took over {CHECK_SECONDS} s")
    lines = proc.stdout.strip().splitlines()
    if proc.returncode == 0 and lines:
        return Verdict(True, seconds=float(json.loads(lines[-1])["seconds"]))
    said = [x.strip() for x in (proc.stderr + proc.stdout).splitlines() if x.strip()]
    last = said[-1] if said else f"exit status {proc.returncode}"
    return Verdict(False, last if proc.returncode > 0 else f"crashed (signal {-proc.returncode}): {last}")


def _reference(path: Path) -> Path:
    """The timed conversion's capture, simulated into `path`."""
    from fmcw_cl.simulator import SimulationConfig, simulate_capture, static

    simulate_capture(path, static(REFERENCE_S, 0.3), REFERENCE_S, seed=1, config=SimulationConfig(snr_db=0.0))
    return path


def _load(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def _save(path: Path, store: dict) -> None:
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_text(json.dumps(store, indent=1))
    tmp.replace(path)


DRIVERS = {"NVIDIA": "libnvidia-opencl.so.1", "AMD": "libamdocl64.so", "Intel": "libigdrcl.so"}
LIBRARY_DIRS = ("/usr/local/nvidia/lib64", "/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/lib",
                "/opt/rocm/lib", "/usr/local/lib")


def unregistered_drivers() -> list[tuple[str, Path]]:
    """GPU OpenCL drivers installed but named by no ICD file, so that no loader sees
    them (an NVIDIA container often has the driver and only PoCL's ICD file):
    (vendor, library path) of each."""
    folders = [Path(os.environ.get("OCL_ICD_VENDORS", "/etc/OpenCL/vendors")), vendors.SYSTEM_VENDORS]
    named = " ".join(f.read_text(errors="replace") for d in folders if d.is_dir() for f in d.glob("*.icd"))
    found = []
    for vendor, lib in DRIVERS.items():
        for d in LIBRARY_DIRS:
            path = Path(d) / lib
            if path.exists() and lib not in named:
                found.append((vendor, path))
                break
    return found

