"""`fmcw-cl simulate`: write a capture of a simulated target with /truth."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click

from fmcw_cl.progress import Progress
from fmcw_cl.simulate import SCENARIOS, SimulationConfig, simulate_capture


@click.command("simulate")
@click.argument("scenario", type=click.Choice(sorted(SCENARIOS)))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--duration", default=None, type=float,
              help="Seconds of capture [default: static 0.05, rail 0.4, jump 0.3].")
@click.option("--seed", default=0, show_default=True, help="Seed of every random draw.")
@click.option("--distance", default=0.3, show_default=True, help="static: target distance (m).")
@click.option("--start", default=0.0, show_default=True,
              help="Scenario time (s) at the capture's first sample (for excerpts).")
@click.option("--noise", default=None, type=float, help="Beat noise, rms ADC codes [25].")
@click.option("--sync-delay", default=None, type=float,
              help="Samples the sync lags the optics [drawn from the seed in +-40].")
@click.option("--thermal-lag-us", default=0.0, show_default=True,
              help="First-order lag (us) of the thermal part of the laser tuning; the capture "
                   "keeps the static G(I) table, as a lab would.")
@click.option("--compress", is_flag=True, help="gzip the ADC channels (small files, slow reads).")
@click.option("-q", "--quiet", is_flag=True, help="No progress.")
def command(scenario, output, duration, seed, distance, start, noise, sync_delay, thermal_lag_us, compress,
            quiet):
    """Simulate SCENARIO (static, rail or jump) into a capture file.

    \b
    Example:
      fmcw-cl simulate jump -o jump.h5 --duration 0.3 --seed 1
      fmcw-cl simulate static -o static.h5 --distance 0.25
    """
    duration = duration or {"static": 0.05, "rail": 0.4, "jump": 0.3}[scenario]
    kwargs = {"distance": distance} if scenario == "static" else {}
    trajectory = SCENARIOS[scenario](duration + start, **kwargs)
    cfg = SimulationConfig()
    if noise is not None:
        cfg = replace(cfg, noise_codes=noise)
    if sync_delay is not None:
        cfg = replace(cfg, sync_delay_samples=sync_delay)
    if thermal_lag_us:
        cfg = replace(cfg, thermal_lag_s=thermal_lag_us * 1e-6)
    bar = Progress(output.name, int(duration * cfg.sample_rate_hz), cfg.sample_rate_hz,
                   enabled=False if quiet else None)
    hidden = simulate_capture(output, trajectory, duration, seed, cfg, start_s=start,
                              compression="gzip" if compress else None, progress=bar)
    bar.close()
    if not quiet:
        click.echo(f"{output}: {scenario}, {duration:g} s, seed {seed}, "
                   f"sync lags optics by {hidden['sync_delay_samples']:+.2f} samples")
