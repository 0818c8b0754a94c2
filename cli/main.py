"""Entry point: the click group and the one-line error policy."""

from __future__ import annotations

import importlib
import sys
import warnings

import click

from fmcw_cl import __version__
from fmcw_cl.errors import FmcwError
from fmcw_cl.options import use_flags
from fmcw_cl.progress import latch_interrupts

# name: (module of cli/, one line of help). A command's module (and numpy, scipy,
# pyopencl, matplotlib, Dask behind it) is imported only when that command runs, so
# `fmcw-cl --help` answers at once; tests/test_cli.py keeps these lines equal to the
# commands' own first docstring lines.
COMMANDS = {
    "process": ("process", "Convert CAPTURE files into tracks (distance, velocity, acceleration)."),
    "calibrate": ("calibrate",
                  "Measure the dynamic chirp from CAPTURE of a static target at --distance."),
    "simulate": ("simulate",
                 "Simulate SCENARIO (static, rail, jump, vibration or creep) into a capture file."),
    "import": ("import_dump",
               "Make a capture from DUMP (interleaved int16 binary, or .npy (N, 2) / (2, N))."),
    "info": ("info", "Describe CAPTURE: duration, periods, sweep bandwidth, ranges, sync delay, levels."),
    "export": ("export", "Write TRACK files as CSV, Parquet or NetCDF tables."),
    "report": ("report",
               "Plot TRACK (distance, velocity, acceleration; spectra; precision) and list its events."),
    "devices": ("devices", "List OpenCL platforms and devices; mark the one `process` would use."),
    "bench": ("bench",
              "Half-sweeps per second, MS/s and the multiple of real time, per stage and end to end."),
}


class LazyGroup(click.Group):
    """A group that imports a command's module only when the command is used."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        return importlib.import_module(f"{__package__}.{COMMANDS[name][0]}").command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        with formatter.section("Commands"):
            formatter.write_dl([(name, text) for name, (_, text) in COMMANDS.items()])


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="fmcw-cl")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """Batch processor for FMCW LiDAR captures (synchronous nonlinearity correction).

    \b
    Example:
      fmcw-cl simulate jump -o jump.h5 --duration 0.3
      fmcw-cl process jump.h5 -o tracks/
    """
    ctx.obj = {"debug": debug}



def main(argv: list[str] | None = None) -> None:
    """Run the CLI; a project error becomes one line on stderr and exit status 1."""
    debug = "--debug" in (sys.argv[1:] if argv is None else argv)
    if not debug:                   # numpy's and the libraries' own warnings are not the user's
        for kind in (RuntimeWarning, DeprecationWarning, FutureWarning):
            warnings.simplefilter("ignore", kind)
    latch_interrupts()
    use_flags()
    try:
        cli.main(args=argv, prog_name="fmcw-cl", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("interrupted", err=True)
        sys.exit(130)
    except click.UsageError as exc:             # one line, with where to read more
        where = exc.ctx.command_path if exc.ctx is not None else "fmcw-cl"
        click.echo(f"error: {exc.format_message()} ({where} -h)", err=True)
        sys.exit(exc.exit_code)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except FmcwError as exc:
        if debug:
            raise
        click.echo(f"error: {exc}", err=True)
        sys.exit(1)
    except KeyboardInterrupt:
        click.echo("interrupted", err=True)
        sys.exit(130)


if __name__ == "__main__":
    main()
