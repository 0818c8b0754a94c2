"""The wheel ships every package: an editable install would hide a missing one."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def declared_packages() -> set[str]:
    text = (ROOT / "pyproject.toml").read_text()
    line = re.search(r"^packages = \[(.*?)\]", text, re.M | re.S).group(1)
    return set(re.findall(r'"([\w.]+)"', line))


def test_every_package_directory_is_declared():
    found = {"fmcw_cl." + ".".join(p.parent.relative_to(ROOT / "fmcw_cl").parts)
             for p in (ROOT / "fmcw_cl").rglob("__init__.py")}
    found = {f.rstrip(".") for f in found}
    found |= {"fmcw_cl.cli", "fmcw_cl.kernels"}          # mapped from cli/ and kernels/
    assert found == declared_packages()


def test_kernels_are_package_data():
    text = (ROOT / "pyproject.toml").read_text()
    assert '"fmcw_cl.kernels" = ["*.cl"]' in text
    from fmcw_cl.kernels import files_of

    from fmcw_cl.opencl.backend import OpenCLBackend

    # every .cl file is part of a program the backend builds, and every program's file ships
    shipped = {p.stem for p in (ROOT / "kernels").glob("*.cl")}
    built = {f for program in OpenCLBackend.programs for f in files_of(program)}
    assert shipped == built
    assert {"lpf", "sync", "resample", "fft", "peak"} <= shipped       # the method's stages
