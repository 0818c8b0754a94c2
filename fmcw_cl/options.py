"""The options of a conversion, defined once for the command line, the Python API and
the engine.

`fmcw-cl process --max-range 0.4`, `fmcw_cl.process(path, max_range=0.4)` and
`Options(max_range=0.4)` are the same option: its name, default, help, type and valid
range live in one `Opt` here. `Options` is the one validated configuration every
conversion runs on: frozen, each field checked at construction, then the rules between
fields (the checks that need the capture's bandwidth, such as the unambiguous range, run
when the plan is made). `click_options` makes the command line's flags from the specs
(a boolean `name` is `--name/--no-name`). Importing this module costs nothing (no numpy).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields

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


def flags_said() -> bool:
    """Whether options are named as command-line flags (the CLI) or keywords (Python)."""
    return _SPELLING["flags"]


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
)

# fields of Options that are not on the command line: the engine's own settings, which
# benchmarks and tests vary
ENGINE = (
    Opt("iterations", 6, int, "De-chirp passes of the tracker.", lo=1, hi=50),
    Opt("chunk_periods", None, int, "Modulation periods per chunk core (default: the processor's, as "
        "many as its device holds).", lo=1, hi=10**7),
    Opt("context_periods", 64, int, "Periods of context on each side of a chunk's core (continuity "
        "across chunk boundaries).", lo=1, hi=4096),
)

# where a conversion runs, not what it computes: not part of Options
RUN = (
    Opt("backend", "auto", str, "Stage implementation; auto: OpenCL if a device is there, else numpy.",
        choices=("auto", "opencl", "numpy")),
    Opt("device", None, str, "OpenCL device: index P or P:D, or a name substring (default: PYOPENCL_CTX, "
        "else a GPU, else the fastest CPU runtime that passes the self-check); see `fmcw-cl devices`."),
)

RANGE_GAP_M = 0.01   # --max-range above --min-range by at least this much


@dataclass(frozen=True)
class Options:
    """What a conversion computes: every field of PROCESS and ENGINE (distances in m),
    each validated at construction (`Opt.check`), then the rules between fields."""

    points: int = 1000
    min_range: float = 0.03
    max_range: float | None = None
    target: str = "auto"
    target_near: float | None = None
    dechirp: bool = True
    range_check: bool = True
    integrate: int | None = None
    chirp: str | None = None
    iterations: int = 6
    chunk_periods: int | None = None
    context_periods: int = 64

    def __post_init__(self) -> None:
        specs = {o.name: o for o in PROCESS + ENGINE}
        for f in fields(self):
            object.__setattr__(self, f.name, specs[f.name].check(getattr(self, f.name)))
        if self.max_range is not None and self.max_range < self.min_range + RANGE_GAP_M:
            raise FmcwError(f"{said('max_range', self.max_range)} m must exceed "
                            f"{said('min_range', self.min_range)} m by at least {RANGE_GAP_M:g} m")

    @property
    def band_m(self) -> tuple[float, float | None]:
        """[min_range, max_range) (m; None: to the end of the spectrum)."""
        return self.min_range, self.max_range


def check(options: dict, spec: tuple[Opt, ...] = PROCESS + RUN, where: str = "") -> dict:
    """Every option of `spec`, from `options` (keywords) or its default, validated."""
    known = {o.name: o for o in spec}
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise FmcwError(f"{where}unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
                        f"the options are {', '.join(known)}")
    return {name: o.check(options.get(name, o.default), where) for name, o in known.items()}


def from_keywords(keywords: dict) -> tuple[Options, str, str | None]:
    """The Options, backend and device of a conversion's keywords (the command line's
    flags or the API's keywords), each validated before any work."""
    values = check(keywords)
    return Options(**{o.name: values[o.name] for o in PROCESS}), values["backend"], values["device"]


def click_options(spec: tuple[Opt, ...] = PROCESS + RUN) -> Callable:
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
