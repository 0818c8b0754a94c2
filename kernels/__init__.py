"""OpenCL C sources of the pipeline's kernels, one stage a file, shipped as package data."""

from importlib.resources import files

# programs built from more than one file (device functions first)
PROGRAMS = {"spectrum": ("lanes", "cycles", "peak", "cfar", "fft", "fft_lanes"),
            "integrate": ("lanes", "peak", "integrate", "integrate_lanes"),
            "lpf": ("lanes", "lpf"), "resample": ("lanes", "resample"), "sync": ("real", "sync"),
            "delay": ("real", "delay"), "survey": ("lanes", "survey"), "phase": ("lanes", "cycles", "phase")}


def files_of(program: str) -> tuple[str, ...]:
    """The kernels/<name>.cl files that make up `program`."""
    return PROGRAMS.get(program, (program,))


def source(name: str) -> str:
    """The OpenCL C text of program `name` (its files concatenated)."""
    return "\n".join(files(__name__).joinpath(f"{f}.cl").read_text() for f in files_of(name))


def sources_digest() -> str:
    """A digest of every kernel source: a device's self-check holds for these sources."""
    import hashlib

    digest = hashlib.sha1()
    for path in sorted(files(__name__).iterdir(), key=lambda p: p.name):
        if path.name.endswith(".cl"):
            digest.update(path.name.encode() + path.read_bytes())
    return digest.hexdigest()[:16]
