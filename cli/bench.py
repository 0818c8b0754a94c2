"""`fmcw-cl bench`: throughput per stage and end to end, for each backend."""

from __future__ import annotations

import json

import click

from fmcw_cl.bench import run
from fmcw_cl.progress import Progress


@click.command("bench")
@click.option("--seconds", default=0.2, show_default=True, help="Length of the simulated capture.")
@click.option("--points", default=1000, show_default=True)
@click.option("--backend", type=click.Choice(["all", "numpy", "opencl"]), default="all",
              show_default=True)
@click.option("--device", default=None, help="OpenCL device (see `fmcw-cl devices`).")
@click.option("--json", "as_json", is_flag=True, help="Rows as JSON on stdout.")
def command(seconds, points, backend, device, as_json):
    """Half-sweeps per second, MS/s and the multiple of real time, per stage and end to end.

    Real time is 100 MS/s per channel = 40 000 half-sweeps/s.

    \b
    Example:
      fmcw-cl bench --seconds 0.2
    """
    backends = ("numpy", "opencl") if backend == "all" else (backend,)
    bar = Progress("simulating", enabled=None if not as_json else False, sample_rate_hz=100e6)
    rows = run(seconds, points, backends, device, progress=bar)
    bar.close()
    if as_json:
        click.echo(json.dumps(rows, indent=2))
        return
    click.echo(f"{'backend':8} {'stage':28} {'s':>8} {'half-sweeps/s':>14} {'MS/s':>8} {'x real time':>12}")
    for r in rows:
        click.echo(f"{r['backend']:8} {r['stage']:28} {r['seconds']:8.4f} {r['half_sweeps_per_s']:14.0f} "
                   f"{r['msamples_per_s']:8.1f} {r['real_time_multiple']:12.3f}")
    for dev in dict.fromkeys(r["device"] for r in rows):
        click.echo(f"device: {dev}")
    seconds_of = {(r["backend"], r["stage"]): r["seconds"] for r in rows}
    for stage in ("end to end (file to track)", "end to end, paper's method"):
        if ("numpy", stage) in seconds_of and ("opencl", stage) in seconds_of:
            click.echo(f"{stage}: OpenCL {seconds_of[('numpy', stage)] / seconds_of[('opencl', stage)]:.2f}x "
                       "faster than numpy")
