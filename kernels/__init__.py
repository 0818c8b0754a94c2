"""OpenCL C sources of the pipeline's kernels, one stage a file, shipped as package data."""

from importlib.resources import files


def source(name: str) -> str:
    """The text of kernels/<name>.cl."""
    return files(__name__).joinpath(f"{name}.cl").read_text()
