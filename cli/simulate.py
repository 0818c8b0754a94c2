"""`fmcw-cl simulate`: write a capture of a simulated target with /truth."""

from __future__ import annotations

from pathlib import Path

import click

import fmcw_cl
from fmcw_cl.progress import Progress
from fmcw_cl.simulator import DURATIONS_S, SCENARIOS, SimulationConfig


def parse_reflector(text: str) -> tuple[float, float]:
    """DIST:AMPLITUDE (metres, ADC codes) of --reflector (fmcw_cl.simulate checks the values)."""
    try:
        dist, amp = (float(x) for x in text.split(":"))
    except ValueError:
        raise click.BadParameter(f"{text!r} is not DIST:AMPLITUDE (e.g. 0.42:800)",
                                 param_hint="--reflector") from None
    return dist, amp


@click.command("simulate")
@click.argument("scenario", type=click.Choice(sorted(SCENARIOS)))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--duration", default=None, type=float,
              help="Seconds of capture [default: static 0.05, rail 0.4, jump 0.3].")
@click.option("--seed", default=0, show_default=True, help="Seed of every random draw.")
@click.option("--distance", default=None, type=float,
              help="static, vibration, creep: target distance (m) [0.3]; jump: the ground's distance "
                   "(m) [0.07].")
@click.option("--start", default=0.0, show_default=True,
              help="Scenario time (s) at the capture's first sample (for excerpts).")
@click.option("--noise", default=None, type=float, help="Beat noise, rms ADC codes [25].")
@click.option("--snr-db", default=None, type=float,
              help="The target's per-sample SNR (dB) at 0.3 m, mid-sweep; sets the beat noise "
                   "instead of --noise (a lab's diffuse target: about 0 dB).")
@click.option("--reflector", "reflectors", multiple=True, metavar="DIST:AMPLITUDE",
              help="A static echo (a wall, a window) at DIST metres with a beat amplitude of "
                   "AMPLITUDE ADC codes at 320 mA (the target's is 500 at 0.3 m); repeatable.")
@click.option("--speckle-ms", default=0.0, show_default=True,
              help="Speckle fading of the target's echo: Rayleigh amplitude, correlation time (ms).")
@click.option("--table-noise-mhz", default=None, type=float,
              help="rms scatter of the offline G(I) table (MHz) [5; an OSA's: 20].")
@click.option("--rin-db-hz", default=None, type=float,
              help="Relative intensity noise of the laser (dB/Hz, e.g. -140) [none].")
@click.option("--sync-delay", default=None, type=float,
              help="Samples the sync lags the optics [drawn from the seed in +-40].")
@click.option("--thermal-lag-us", default=0.0, show_default=True,
              help="First-order lag (us) of the thermal part of the laser tuning; the capture "
                   "keeps the static G(I) table, as a lab would.")
@click.option("--lab", is_flag=True,
              help="A lab's instrument: an intensity triangle of +-150 codes under 600 codes rms of "
                   "noise, a G(I) table with 20 MHz scatter (--noise, --snr-db, --table-noise-mhz still "
                   "apply).")
@click.option("--no-headroom", is_flag=True,
              help="No gain setting: noise peaks reach full scale (--noise 3000: 0.7 % of the codes).")
@click.option("--compress", is_flag=True, help="gzip the ADC channels (small files, slow reads).")
@click.option("--overwrite", is_flag=True, help="Replace OUTPUT where it exists (else that is refused).")
@click.option("--amplitude-um", default=None, type=float, help="vibration: its amplitude (um) [50].")
@click.option("--frequency-hz", default=None, type=float, help="vibration: its frequency (Hz) [1000].")
@click.option("--speed-mmps", default=None, type=float, help="creep: its speed (mm/s) [1].")
@click.option("-q", "--quiet", is_flag=True, help="No progress.")
def command(scenario, output, duration, seed, distance, start, noise, snr_db, reflectors, speckle_ms,
            table_noise_mhz, rin_db_hz, sync_delay, thermal_lag_us, lab, no_headroom, compress, overwrite,
            amplitude_um, frequency_hz, speed_mmps, quiet):
    """Simulate SCENARIO (static, rail, jump, vibration or creep) into a capture file.

    \b
    Example:
      fmcw-cl simulate jump -o jump.h5 --duration 0.3 --seed 1
      fmcw-cl simulate static -o static.h5 --distance 0.25
      fmcw-cl simulate jump -o wall.h5 --snr-db 0 --reflector 0.42:800 --speckle-ms 3
      fmcw-cl simulate static -o lab.h5 --lab --distance 0.4
      fmcw-cl simulate vibration -o vib.h5 --amplitude-um 50 --frequency-hz 1000
    """
    reflectors = tuple(parse_reflector(r) for r in reflectors)
    duration = DURATIONS_S[scenario] if duration is None else duration
    fs = SimulationConfig.sample_rate_hz
    bar = Progress(output.name, int(duration * fs), fs, enabled=False if quiet else None)
    hidden = fmcw_cl.simulate(output, scenario, duration=duration, seed=seed, distance=distance, start=start,
                              noise=noise, snr_db=snr_db, reflectors=reflectors, speckle_ms=speckle_ms,
                              table_noise_mhz=table_noise_mhz, rin_db_hz=rin_db_hz, sync_delay=sync_delay,
                              thermal_lag_us=thermal_lag_us, compress=compress, lab=lab,
                              no_headroom=no_headroom, overwrite=overwrite, amplitude_um=amplitude_um,
                              frequency_hz=frequency_hz, speed_mmps=speed_mmps, progress=bar)
    bar.close()
    if not quiet:
        click.echo(f"{output}: {scenario}, {duration:g} s, seed {seed}, "
                   f"sync lags optics by {hidden['sync_delay_samples']:+.2f} samples")
