"""`fmcw-cl calibrate`: the real chirp from a capture of a static target."""

from __future__ import annotations

from pathlib import Path

import click

import fmcw_cl

DISTANCE_WARN = 0.05    # --distance this far from the G(I) table's own distance is warned of


@click.command("calibrate")
@click.argument("capture", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--distance", required=True, type=float,
              help="The static target's distance R (m), as well known as the result must be.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The chirp file to write (use it with `process --chirp`).")
@click.option("--periods", default=2000, show_default=True, help="Modulation periods averaged.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing.")
def command(capture, distance, output, periods, quiet):
    """Measure the dynamic chirp from CAPTURE of a static target at --distance.

    \b
    Example:
      fmcw-cl calibrate rail_0p300m.h5 --distance 0.300 -o chirp.h5
      fmcw-cl process run7.h5 -o tracks/ --chirp chirp.h5
    """
    chirp = fmcw_cl.calibrate(capture, distance, output, periods=periods,
                              warn=lambda message: click.echo(message, err=True))
    a = chirp.attrs
    table = float(a["table_distance_m"])
    if abs(table / distance - 1) > DISTANCE_WARN:
        click.echo(f"warning: {capture}: the target measures {table:.4f} m by the capture's G(I) table, "
                   f"{100 * (distance / table - 1):+.1f} % from --distance {distance:g}; the calibration "
                   f"scales every distance by {distance / table:.3f} (a table is rarely "
                   f"{100 * DISTANCE_WARN:.0f} % off): check --distance", err=True)
    if quiet:
        return
    click.echo(f"{capture} -> {output}\n"
               f"  sweep {a['bandwidth_rising_hz'] / 1e9:.3f} GHz rising, "
               f"{a['bandwidth_falling_hz'] / 1e9:.3f} GHz falling (static G(I): "
               f"{a['static_bandwidth_hz'] / 1e9:.3f} GHz); LUT band {a['bandwidth_hz'] / 1e9:.3f} GHz\n"
               f"  {a['periods_used']} periods, residual phase {a['residual_phase_rad']:.3f} rad rms; the "
               f"target at {table:.4f} m by the G(I) table")
