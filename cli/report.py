"""`fmcw-cl report`: a track's pictures and event table."""

from __future__ import annotations

from pathlib import Path

import click

from fmcw_cl.report import make_report


@click.command("report")
@click.argument("track", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--outdir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for kinematics.png, echoes.png, spectra.png, precision.png, events.md/json.")
@click.option("--capture", default=None, type=click.Path(dir_okay=False, path_type=Path),
              help="The source capture (default: the track's `source` attribute); gives the "
                   "truth overlay and the spectra.")
@click.option("--at", "at_ms", default=None, type=float,
              help="Centre of the spectra's stretch (ms) [default: the farthest moment where the target "
                   "is slow].")
@click.option("--span", "span_ms", default=10.0, show_default=True,
              help="Length of the spectra's stretch (ms).")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing.")
def command(track, outdir, capture, at_ms, span_ms, quiet):
    """Plot TRACK (distance, velocity, acceleration; spectra; precision) and list its events.

    \b
    Example:
      fmcw-cl simulate jump -o jump.h5
      fmcw-cl process jump.h5 -o tracks/
      fmcw-cl report tracks/jump.track.h5 -o report/
    """
    got = make_report(track, outdir, capture, None if at_ms is None else at_ms / 1e3, span_ms / 1e3)
    for what, why in got["left_out"].items():
        click.echo(f"note: {track}: {what} left out: {why}", err=True)
    if quiet:
        return
    for path in got["written"]:
        click.echo(path)
    click.echo((Path(outdir) / "events.md").read_text(encoding="utf-8"), nl=False)
