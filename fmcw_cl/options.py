"""The options of a conversion, defined once for the command line and the Python API.

`fmcw-cl process --max-range 0.4` and `fmcw_cl.process(path, max_range=0.4)` are the
same option: its name, default, help, type and valid range live in one `Opt` here;
`click_options` makes the command line's flags from them (a boolean `name` is
`--name/--no-name`) and `check` validates keyword arguments with errors that carry the
numbers. Importing this module costs nothing (no numpy).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from .errors import FmcwError

# errors name an option as the user gave it: --max-range 5 on the command line (whose
# entry sets this, for the whole process), max_range=5 in Python
_SPELLING = {"flags": False}


def flag_of(name: str) -> str:
    """The command-line flag of keyword `name`: max_range -> --max-range."""
    return "--" + name.replace("_", "-")


def use_flags() -> None:
    """Name options as command-line flags in errors from now on (the CLI's entry)."""
    _SPELLING["flags"] = True


def said(name: str, value=None) -> str:
    """Option `name` (a keyword, e.g. "max_range") as the user spells it, with `value`
    when given: "--max-range 5" or "max_range=5"."""
    flags = _SPELLING["flags"]
    key = flag_of(name) if flags else name
    if value is None:
        return key
    shown = f"{value:g}" if isinstance(value, float) else str(value) if flags else repr(value)
    return f"{key} {shown}" if flags else f"{key}={shown}"

MAX_POINTS = 16384    # a 32768-point FFT per half-sweep; ~2500 samples are resampled


@dataclass(frozen=True)
class Opt:
    """One option: Python keyword `name` (command line: --name with dashes)."""

    name: str
    default: object
    kind: type
    help: str
    lo: float | None = None        # valid values: lo <= value (< hi when given)
    hi: float | None = None
    choices: tuple[str, ...] | None = None
    why: str = ""                  # what the bounds are, for the error message
    metavar: str | None = None     # the value's name in --help (default: its type)

    @property
    def flag(self) -> str:
        return flag_of(self.name)

    def check(self, value, where: str = "") -> object:
        """`value` converted to the option's type; an FmcwError naming the numbers when
        it is out of range or of the wrong kind."""
        if value is None and self.default is None:
            return None
        if self.kind is bool:
            if not isinstance(value, bool):
                raise FmcwError(f"{where}{said(self.name, value)} must be True or False")
            return value
        try:
            got = self.kind(value)
        except (TypeError, ValueError):
            raise FmcwError(f"{where}{said(self.name, value)} is not {self.kind.__name__}") from None
        if self.kind is int and got != value:
            raise FmcwError(f"{where}{said(self.name, value)} is not a whole number")
        if self.choices is not None and got not in self.choices:
            raise FmcwError(f"{where}{said(self.name, got)} is not one of {', '.join(self.choices)}")
        if self.lo is not None and got < self.lo:
            raise FmcwError(f"{where}{said(self.name, got)} is below {self.lo:g}")
        if self.hi is not None and got > self.hi:
            raise FmcwError(f"{where}{said(self.name, got)} exceeds {self.hi:g}{self.why}")
        return got


PROCESS = (
    Opt("points", 1000, int, "Resampling intervals per half-sweep (unambiguous range N c / 4nB).",
        lo=16, hi=MAX_POINTS, why=", the most points a half-sweep is resampled to (a 32768-point FFT)"),
    Opt("min_range", 0.03, float,
        "Ignore peaks below this distance (m): DC, intensity ramp, lens reflection.", lo=0.0),
    Opt("max_range", None, float, "Ignore peaks beyond this distance (m): a wall or a window behind the "
        "target. The target is chosen in [min-range, max-range) (--target).", lo=0.0),
    Opt("target", "auto", str, "Which echo is the target: auto (a moving echo where there is one, fixed "
        "echoes it does not reach left out of the band; docs/pipeline.md), moving (refuse a capture "
        "without one), nearest, or strongest (pair by pair).", choices=("auto", "moving", "nearest",
                                                                        "strongest")),
    Opt("target_near", None, float, "The target is the echo nearest to this distance (m), fixed or "
        "moving; the echoes beside it are left out of the band.", lo=0.0),
    Opt("dechirp", True, bool, "Doppler de-chirp tracking; --no-dechirp: the paper's method alone."),
    Opt("range_check", True, bool, "The 2N-point resampling that flags targets beyond the unambiguous range "
        "(--no-range-check skips it)."),
    Opt("integrate", None, int, "Half-sweeps of a direction whose spectra are summed per output (1: none; "
        "the time resolution becomes K periods); default: chosen per chunk from the measured SNR, 1 "
        "unless the single half-sweeps are too weak.", lo=1, hi=32, why=", the most half-sweeps integrated"),
    Opt("chirp", None, str, "A chirp calibration (fmcw-cl calibrate) to use instead of the G(I) table.",
        metavar="FILE"),
    Opt("backend", "auto", str, "Stage implementation; auto: OpenCL if a device is there, else numpy.",
        choices=("auto", "opencl", "numpy")),
    Opt("device", None, str, "OpenCL device: index P or P:D, or a name substring (default: PYOPENCL_CTX, "
        "else the first GPU, else the first device); see `fmcw-cl devices`."),
)

# engine.Options field each processing option sets (backend and device choose where it runs)
FIELDS = {"points": "points", "min_range": "min_range_m", "max_range": "max_range_m", "dechirp": "dechirp",
          "range_check": "range_check", "chirp": "chirp", "integrate": "integrate", "target": "target",
          "target_near": "target_near_m"}


def check(options: dict, spec: tuple[Opt, ...] = PROCESS, where: str = "") -> dict:
    """Every option of `spec`, from `options` (keywords) or its default, validated."""
    known = {o.name: o for o in spec}
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise FmcwError(f"{where}unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
                        f"the options are {', '.join(known)}")
    return {name: o.check(options.get(name, o.default), where) for name, o in known.items()}


def click_options(spec: tuple[Opt, ...] = PROCESS) -> Callable:
    """Decorator adding the command-line flags of `spec` to a click command."""
    import click

    def decorate(func):
        for o in reversed(spec):
            if o.kind is bool:
                flags = f"{o.flag}/--no-{o.flag[2:]}"
                func = click.option(flags, o.name, default=o.default, show_default=True, help=o.help)(func)
            elif o.choices:
                func = click.option(o.flag, o.name, type=click.Choice(o.choices), default=o.default,
                                    show_default=True, help=o.help)(func)
            else:
                func = click.option(o.flag, o.name, type=o.kind, default=o.default, metavar=o.metavar,
                                    show_default=o.default is not None, help=o.help)(func)
        return func
    return decorate
