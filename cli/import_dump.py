"""`fmcw-cl import`: raw DAQ dumps and an OSA G(I) table to a capture."""

from __future__ import annotations

from pathlib import Path

import click

from fmcw_cl.capture_format import Modulation
from fmcw_cl.ingest import import_capture
from fmcw_cl.progress import Progress


@click.command("import")
@click.argument("dump", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--tuning", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="OSA CSV of the G(I) table: current (mA), wavelength (nm) per row.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The capture file to write.")
@click.option("--sample-rate", default=None, type=float,
              help="ADC sample rate (Hz) [a dump: 100e6; a TDMS recording: from its wf_increment].")
@click.option("--frequency", default=20e3, show_default=True,
              help="Triangle repetition frequency of the injection current (Hz).")
@click.option("--current-min", default=0.160, show_default=True, help="Lowest injection current (A).")
@click.option("--current-max", default=0.480, show_default=True, help="Highest injection current (A).")
@click.option("--bits", default=None, type=int,
              help="Effective ADC resolution [from the file: a TDMS recording's raw codes are int16 "
                   "(16), its volts 14; a dump's 14, or 16 where its codes go beyond 14 bits].")
@click.option("--order", type=click.Choice(["beat,sync", "sync,beat"]), default="beat,sync",
              show_default=True, help="Channel order in the dump.")
@click.option("--refractive-index", default=None, type=float, help="Of the medium [1.0].")
@click.option("--air", is_flag=True, help="The OSA reports wavelengths in air (not vacuum).")
@click.option("--beat-channel", default=None, metavar="GROUP/CHANNEL",
              help="TDMS: the beat channel [the first channel of the first group].")
@click.option("--sync-channel", default=None, metavar="GROUP/CHANNEL",
              help="TDMS: the sync channel [the second channel of the first group].")
@click.option("--full-scale-volts", default=None, type=float,
              help="TDMS float (scaled) channels: the ADC's input range +-V, back to codes.")
@click.option("-q", "--quiet", is_flag=True, help="No progress.")
def command(dump, tuning, output, sample_rate, frequency, current_min, current_max, bits, order,
            refractive_index, air, beat_channel, sync_channel, full_scale_volts, quiet):
    """Make a capture from DUMP (interleaved int16 binary, or .npy (N, 2) / (2, N)).

    DUMP may also be a LabVIEW TDMS recording (.tdms): channels by GROUP/CHANNEL, its
    sample rate from wf_increment, integer codes, DAQmx raw data (read raw) or scaled
    volts (--full-scale-volts). Samples beyond the ADC's full scale are clipped, and
    the warning says how many.

    \b
    Example:
      fmcw-cl import run7.bin --tuning dfb_osa.csv -o run7.h5 --sample-rate 100e6 \\
          --frequency 20e3 --current-min 0.160 --current-max 0.480
      fmcw-cl import run8.tdms --tuning dfb_osa.csv -o run8.h5 --beat-channel adc/beat \\
          --sync-channel adc/sync
    """
    if sample_rate is None and dump.suffix.lower() != ".tdms":
        sample_rate = 100e6
    bar = Progress(output.name, enabled=False if quiet else None)
    try:
        import_capture(dump, tuning, output, sample_rate, Modulation(frequency, current_min, current_max),
                       bits, order, refractive_index, air, progress=bar, beat_channel=beat_channel,
                       sync_channel=sync_channel, full_scale_volts=full_scale_volts,
                       warn=lambda m: click.echo(f"warning: {m}", err=True))
    finally:
        bar.close()
    if not quiet:
        click.echo(f"{dump} + {tuning} -> {output}")
