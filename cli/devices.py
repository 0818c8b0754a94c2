"""`fmcw-cl devices`: the OpenCL platforms and devices seen, and which one is used."""

from __future__ import annotations

import os

import click

from fmcw_cl.errors import FmcwError
from fmcw_cl.opencl.choice import (
    CPU,
    GPU,
    SIMULATOR,
    cached,
    cannot_compile,
    describe,
    devices,
    rank,
    select_device,
    unregistered_drivers,
)
from fmcw_cl.opencl.vendors import pip_runtimes

KINDS = {GPU: "GPU", CPU: "CPU", SIMULATOR: "simulator, never chosen automatically"}
AUTOMATIC = ("the automatic choice: GPUs first, then CPUs; of those, the fastest that passes the self-check; "
             "never a simulator")


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
        chosen = select_device(device, say=lambda line: click.echo(line, err=True))
    except FmcwError as exc:
        chosen = None
        click.echo(f"no device selected: {exc}", err=True)
    for p, d, _, dev in seen:
        mark = "*" if chosen is not None and dev.int_ptr == chosen.int_ptr else " "
        mem = dev.global_mem_size / 2**30
        click.echo(f"{mark} {p}:{d}  {describe(dev)}  ({KINDS.get(rank(dev), 'other')}, "
                   f"{dev.max_compute_units} units, {mem:.1f} GiB, {dev.version.strip()}){_verdict(dev)}")
    if chosen is not None:
        why = (f"the selector {device!r}" if device else "PYOPENCL_CTX" if os.environ.get("PYOPENCL_CTX")
               else AUTOMATIC)
        click.echo(f"used: {describe(chosen)} ({why})")
    for dist, lib in pip_runtimes().items():
        click.echo(f"pip's {dist}: {lib} (registered by fmcw-cl)", err=True)
    for vendor, lib in unregistered_drivers():
        click.echo(f"note: the {vendor} OpenCL driver {lib} is installed but no ICD file names it, so it is "
                   f"not seen; to use it: echo {lib} > /etc/OpenCL/vendors/{vendor.lower()}.icd", err=True)
    if not seen:
        raise FmcwError("no OpenCL device found: pip install pocl-binary-distribution")
    if check and chosen is not None:
        from fmcw_cl.opencl.selftest import check as run_check

        run_check(device)


def _verdict(dev) -> str:
    """What is known of a device's self-check, for its line."""
    if rank(dev) == SIMULATOR:
        return ""
    broken = cannot_compile(dev)
    if broken:
        return f"  cannot compile: {broken}"
    v = cached(dev)
    return "  not checked" if v is None else f"  self-check {v}"
