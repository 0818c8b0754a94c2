"""Entry point: the click group and the one-line error policy."""

from __future__ import annotations

import sys

import click

from fmcw_cl import __version__
from fmcw_cl.errors import FmcwError

from . import bench, calibrate, devices, import_dump, info, process, report, simulate


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
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


for command in (process.command, calibrate.command, simulate.command, import_dump.command, info.command,
                report.command, devices.command, bench.command):
    cli.add_command(command)


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; a project error becomes one line on stderr and exit status 1."""
    debug = "--debug" in (sys.argv[1:] if argv is None else argv)
    try:
        cli.main(args=argv, prog_name="fmcw-cl", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("interrupted", err=True)
        sys.exit(130)
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
