"""`fmcw-cl devices`: the OpenCL platforms and devices seen, and which one is used."""

from __future__ import annotations

import os

import click

from fmcw_cl.errors import FmcwError
from fmcw_cl.opencl.context import (
    CPU,
    GPU,
    SIMULATOR,
    cannot_compile,
    describe,
    devices,
    rank,
    select_device,
    unregistered_drivers,
)

KINDS = {GPU: "GPU", CPU: "CPU", SIMULATOR: "simulator, never chosen automatically"}


@click.command("devices")
@click.option("--device", default=None, help="Selector to resolve (index P[:D] or name substring).")
@click.option("--check", is_flag=True, help="Run every kernel of the pipeline on the used device against "
              "its numpy twin (small inputs, seconds).")
def command(device, check):
    """List OpenCL platforms and devices; mark the one `process` would use.

    \b
    Example:
      fmcw-cl devices
      PYOPENCL_CTX=0:0 fmcw-cl devices
      fmcw-cl devices --device nvidia --check
    """
    seen = devices()
    try:
        chosen = select_device(device)
    except FmcwError as exc:
        chosen = None
        click.echo(f"no device selected: {exc}", err=True)
    for p, d, _, dev in seen:
        mark = "*" if chosen is not None and dev.int_ptr == chosen.int_ptr else " "
        mem = dev.global_mem_size / 2**30
        broken = None if rank(dev) == SIMULATOR else cannot_compile(dev)
        click.echo(f"{mark} {p}:{d}  {describe(dev)}  ({KINDS.get(rank(dev), 'other')}, "
                   f"{dev.max_compute_units} units, {mem:.1f} GiB, {dev.version.strip()})"
                   + (f"  cannot compile: {broken}" if broken else ""))
    if chosen is not None:
        why = (f"the selector {device!r}" if device else "PYOPENCL_CTX" if os.environ.get("PYOPENCL_CTX")
               else "the automatic choice: GPUs first, then CPUs, the first that compiles, never a simulator")
        click.echo(f"used: {describe(chosen)} ({why})")
    for vendor, lib in unregistered_drivers():
        click.echo(f"note: the {vendor} OpenCL driver {lib} is installed but no ICD file names it, so it is "
                   f"not seen; to use it: echo {lib} > /etc/OpenCL/vendors/{vendor.lower()}.icd", err=True)
    if not seen:
        raise FmcwError("no OpenCL device found: pip install pocl-binary-distribution")
    if check and chosen is not None:
        from fmcw_cl.opencl.selftest import check as run_check

        run_check(device)
