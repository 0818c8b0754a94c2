"""`fmcw-cl bench`: throughput per stage and end to end, for each backend."""

from __future__ import annotations

import json
from pathlib import Path

import click

from fmcw_cl.bench import run
from fmcw_cl.options import MAX_POINTS
from fmcw_cl.progress import Progress


@click.command("bench")
@click.option("--seconds", default=0.2, show_default=True, type=click.FloatRange(0.005, 60),
              help="Length of the simulated capture (s).")
@click.option("--points", default=1000, show_default=True, type=click.IntRange(16, MAX_POINTS),
              help="Resampling intervals per half-sweep (as `process --points`).")
@click.option("--backend", type=click.Choice(["all", "numpy", "opencl"]), default="all",
              show_default=True)
@click.option("--device", default=None, help="OpenCL device (see `fmcw-cl devices`).")
@click.option("--json", "as_json", is_flag=True, help="Rows as JSON on stdout.")
@click.option("--captures", "folder", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder where the simulated captures are kept and found, for runs of the same "
                   "--seconds to share (default: a temporary one).")
def command(seconds, points, backend, device, as_json, folder):
    """Half-sweeps per second, MS/s and the multiple of real time, per stage and end to end.

    Real time is 100 MS/s per channel = 40 000 half-sweeps/s.

    \b
    Example:
      fmcw-cl bench --seconds 0.2
    """
    backends = ("numpy", "opencl") if backend == "all" else (backend,)
    bar = Progress("simulating", enabled=None if not as_json else False, sample_rate_hz=100e6)
    rows = run(seconds, points, backends, device, progress=bar, folder=folder)
    bar.close()
    if as_json:
        click.echo(json.dumps(rows, indent=2))
        return
    click.echo(f"{'backend':8} {'stage':30} {'s':>8} {'half-sweeps/s':>14} {'MS/s':>8} {'x real time':>12} "
               f"{'of end to end':>14}")
    for r in rows:
        share = r["share_of_end_to_end"]
        click.echo(f"{r['backend']:8} {r['stage']:30} {r['seconds']:8.4f} {r['half_sweeps_per_s']:14.0f} "
                   f"{r['msamples_per_s']:8.1f} {r['real_time_multiple']:12.3f} "
                   + (f"{share:13.0%}" if share == share else f"{'':>13}"))
    click.echo("end to end, where the time goes (one more run each):")
    for r in rows:
        if "host_cpu_ms_per_s" not in r:
            continue
        line = (f"  {r['backend']:7} {r['stage']:28} host CPU {r['host_cpu_ms_per_s']:6.0f} ms per s of "
                f"capture ({r['host_share_of_wall']:.0%} of the wall)")
        if "launches_per_chunk" in r:
            mib_up, mib_down = r["upload_bytes_per_chunk"] / 2**20, r["download_bytes_per_chunk"] / 2**20
            line += (f"; device busy {r['device_busy_share']:.0%}; per chunk ({r['chunks']}): "
                     f"{r['launches_per_chunk']:.0f} launches, "
                     f"{r['uploads_per_chunk']:.0f} uploads ({mib_up:.1f} MiB), "
                     f"{r['downloads_per_chunk']:.0f} downloads ({mib_down:.1f} MiB)")
        click.echo(line)
    for dev in dict.fromkeys(r["device"] for r in rows):
        click.echo(f"device: {dev}")
    seconds_of = {(r["backend"], r["stage"]): r["seconds"] for r in rows}
    for stage in dict.fromkeys(r["stage"] for r in rows if r["stage"].startswith("end to end")):
        if ("numpy", stage) in seconds_of and ("opencl", stage) in seconds_of:
            click.echo(f"{stage}: OpenCL {seconds_of[('numpy', stage)] / seconds_of[('opencl', stage)]:.2f}x "
                       "faster than numpy")
