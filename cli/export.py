"""`fmcw-cl export`: tracks to CSV, Parquet or NetCDF, for tools other than Python."""

from __future__ import annotations

import sys
from pathlib import Path

import click


@click.command("export")
@click.argument("tracks", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--outdir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for <track stem>.csv / .parquet / .nc.")
@click.option("--format", "fmt", type=click.Choice(["csv", "parquet", "netcdf"]), default="csv",
              show_default=True,
              help="csv and parquet: one table; netcdf: pairs and half-sweeps, with units.")
@click.option("--per", type=click.Choice(["pair", "object", "sweep", "echo"]), default="pair",
              show_default=True,
              help="The table of csv and parquet: one row per pair of the target, per pair of every "
                   "object (with its id and kind), per half-sweep or per echo.")
def command(tracks, outdir, fmt, per):
    """Write TRACK files as CSV, Parquet or NetCDF tables.

    \b
    Example:
      fmcw-cl export tracks/*.track.h5 -o tables/ --format parquet
      fmcw-cl export tracks/jump.track.h5 -o tables/ --format netcdf
    """
    from fmcw_cl.atomic import output_folder
    from fmcw_cl.errors import FmcwError
    from fmcw_cl.tables import FORMATS, export
    from fmcw_cl.track import read_track

    output_folder(outdir)
    failed = 0
    for path in tracks:
        out = outdir / (path.name.removesuffix(".h5").removesuffix(".track") + FORMATS[fmt])
        try:
            try:
                track = read_track(path)
            except (OSError, ValueError, KeyError) as exc:
                raise FmcwError(f"{path}: not a readable track file ({exc})") from None
            export(track, out, fmt, per)
        except FmcwError as exc:
            click.echo(f"error: {exc}", err=True)
            failed += 1
            continue
        click.echo(f"{path} -> {out}")
    if failed:
        sys.exit(1)
