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

    from fmcw_cl.opencl.processor import OpenCLProcessor

    # every .cl file is part of a program the backend builds, and every program's file ships
    shipped = {p.stem for p in (ROOT / "kernels").glob("*.cl")}
    built = {f for program in OpenCLProcessor.programs for f in files_of(program)}
    assert shipped == built
    assert {"lpf", "sync", "resample", "fft", "peak"} <= shipped       # the method's stages


def test_the_checkout_is_importable_without_the_install(tmp_path):
    """From the repository's root the source folder fmcw_cl/ shadows the installed
    package: its kernels and command line are found beside it (cli/, kernels/), and the
    README's Python example runs there. The editable install's finder is removed, as a
    plain `pip install .` would leave nothing to map them."""
    import os
    import subprocess
    import sys

    readme = (ROOT / "README.md").read_text()
    block = re.search(r"## From Python\n\n```python\n(.*?)```", readme, re.S).group(1)
    script = tmp_path / "checkout.py"
    script.write_text(
        "import sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in repr(f).lower()]\n"
        "from fmcw_cl.kernels import source\n"
        "import fmcw_cl.cli.main\n"
        f"assert source('lpf') and fmcw_cl.cli.main.__file__.startswith({str(ROOT / 'cli')!r})\n"
        + block + "assert track.valid.mean() > 0.9 and len(pairs) == track.time_s.size\n")
    env = {k: v for k, v in os.environ.items() if k.startswith("POCL")}
    env.update(PYTHONPATH=str(ROOT), PATH="/usr/bin:/bin", MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(script)], cwd=ROOT, capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
