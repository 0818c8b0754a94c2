"""The report's pictures (matplotlib, headless): the paper's Fig. 10, 5/6(a) and 6(c)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; never needs a display

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..capture_format import Truth  # noqa: E402
from ..evaluate import crb_pair_m, eta_from_peak_snr, truth_at  # noqa: E402
from ..track import Track  # noqa: E402
from .events import Event  # noqa: E402
from .spectra import Spectra  # noqa: E402

DC_M = 0.004     # the DC's and the intensity ramp's lobe: the spectra's lines below --min-range lie beyond
PANELS = (("distance_m", "distance (m)"), ("velocity_mps", "velocity (m/s)"),
          ("acceleration_mps2", "acceleration (m/s²)"))


def kinematics(track: Track, path: Path, truth: Truth | None = None,
               events: list[Event] = ()) -> Path:
    """Distance, velocity and acceleration over time (ms) in three stacked panels.

    Invalid pairs are gaps (NaN); the true trajectory is overlaid dashed when given,
    and the events are marked on their panel.
    """
    t_ms = 1e3 * track.time_s
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 8), constrained_layout=True)
    true = truth_at(truth, track.time_s) if truth is not None else None
    shown = (track.valid, track.velocity_valid, track.acceleration_valid)   # each where valid itself
    for k, (ax, (name, label)) in enumerate(zip(axes, PANELS, strict=True)):
        y = np.where(shown[k], getattr(track, name), np.nan)
        ref, scale, label = _scaled(y, name, label)
        ax.plot(t_ms, (y - ref) * scale, color="C0", lw=1.0, label="measured")
        if true is not None:
            ax.plot(t_ms, (true[k] - ref) * scale, color="k", lw=0.8, ls="--", label="truth")
        marks = [e for e in events if e.quantity == name]
        if marks:
            ax.plot([1e3 * e.time_s for e in marks], [(e.value - ref) * scale for e in marks], "o", ms=5,
                    mfc="none", color="C3", label="events")
        ax.set_ylabel(label)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(alpha=0.3)
    if not track.acceleration_valid.any() and track.valid.any():
        axes[2].text(0.5, 0.5, "no run of verified velocities as long as the acceleration's window",
                     transform=axes[2].transAxes, ha="center", va="center", fontsize=9, color="0.4")
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("time (ms)")
    valid = 100 * np.mean(track.valid) if track.pairs else 0.0
    axes[0].set_title(f"{Path(str(track.attrs.get('source', ''))).name}: {track.pairs} pairs "
                      f"every {1e6 * _pair_step(track):.0f} µs, {valid:.1f} % valid")
    fig.savefig(path, dpi=120, format="png")
    plt.close(fig)
    return path


def _scaled(y: np.ndarray, name: str, label: str) -> tuple[float, float, str]:
    """(reference, scale, axis label) that keep a still target's axis readable: its
    distances in um about their mean in mm (not 0.300006 m), small velocities in mm/s."""
    finite = y[np.isfinite(y)]
    if name == "distance_m" and finite.size and np.ptp(finite) < 1e-3:
        ref = float(np.round(np.median(finite), 5))          # to 10 um: a round number of mm
        return ref, 1e6, f"distance − {ref * 1e3:.3f} mm (µm)"
    if name == "velocity_mps" and finite.size and np.abs(finite).max() < 1e-2:
        return 0.0, 1e3, "velocity (mm/s)"
    return 0.0, 1.0, label


def _pair_step(track: Track) -> float:
    return float(np.median(np.diff(track.time_s))) if track.pairs > 1 else float("nan")


def spectra(sp: Spectra, path: Path, chosen: int, max_range_m: float, min_range_m: float = 0.0) -> Path:
    """Waterfalls before/after the correction, and one half-sweep's spectra compared.

    The waterfalls show the half-sweeps of the chosen one's direction only: rising and
    falling sweeps of a moving target differ by the Doppler shift, and interleaved they
    would stripe the picture. Below `min_range_m` (not searched) lie the DC, the laser's
    intensity ramp and internal reflections (a collimating lens's, 12 mm in the
    simulator): that stretch is shaded and its strongest line named.
    """
    fig = plt.figure(figsize=(11, 8), constrained_layout=True)
    grid = fig.add_gridspec(2, 2, height_ratios=[3, 2])
    same = sp.rising == sp.rising[chosen]
    t_ms = 1e3 * sp.time_s
    direction = "rising" if sp.rising[chosen] else "falling"
    for col, (axis, db, title) in enumerate((
            (sp.raw_distance_m, sp.raw_db, "before: plain FFT of the time samples"),
            (sp.distance_m, sp.corrected_db, "after: resampled at uniform optical frequency"))):
        ax = fig.add_subplot(grid[0, col])
        keep = axis <= max_range_m
        im = ax.imshow(db[same][:, keep].T, origin="lower", aspect="auto", cmap="viridis",
                       vmin=-40, vmax=0, interpolation="nearest",
                       extent=(t_ms[same][0], t_ms[same][-1], 1e3 * axis[0], 1e3 * axis[keep][-1]))
        ax.axvline(t_ms[chosen], color="w", lw=0.8, ls=":")
        if min_range_m > 0:
            ax.axhspan(1e3 * axis[0], 1e3 * min_range_m, color="w", alpha=0.25, lw=0)
        ax.set_title(f"{title}\n(current-{direction} half-sweeps)", fontsize=10)
        ax.set_xlabel("time (ms)")
        ax.set_ylabel("distance (mm)")
    fig.colorbar(im, ax=fig.axes, label="power (dB re. peak)", shrink=0.6, location="right")
    ax = fig.add_subplot(grid[1, :])
    for axis, db, label in ((sp.raw_distance_m, sp.raw_db, "before correction"),
                            (sp.distance_m, sp.corrected_db, "after correction")):
        keep = axis <= max_range_m
        ax.plot(1e3 * axis[keep], db[chosen, keep], lw=1.0, label=label)
    if min_range_m > 0:
        below = (sp.distance_m > DC_M) & (sp.distance_m < min_range_m)
        ax.axvspan(0, 1e3 * min_range_m, color="0.85", lw=0, zorder=0)
        if below.any():
            k = int(np.flatnonzero(below)[np.argmax(sp.corrected_db[chosen, below])])
            line_mm = 1e3 * sp.distance_m[k]
            ax.annotate(f"below --min-range ({1e3 * min_range_m:.0f} mm), not searched: DC, intensity ramp,\n"
                        f"internal reflections (a lens's; the strongest here at {line_mm:.0f} mm)",
                        (1e3 * sp.distance_m[k], sp.corrected_db[chosen, k]), xytext=(40, 14),
                        textcoords="offset points", fontsize=8, va="bottom",
                        bbox={"fc": "w", "ec": "0.6", "lw": 0.5}, arrowprops={"arrowstyle": "->", "lw": 0.6})
    ax.set_title(f"half-sweep at {t_ms[chosen]:.3f} ms (current {direction})", fontsize=10)
    ax.set_xlabel("distance (mm)")
    ax.set_ylabel("power (dB re. peak)")
    ax.set_ylim(-60, 3)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110, format="png")
    plt.close(fig)
    return path


def precision(track: Track, path: Path, true_distance_m: float | None = None) -> Path:
    """Histogram of a static target's distance with its Gaussian fit (the paper's Fig. 6c)."""
    d = track.distance_m[track.valid]
    mean, std = float(np.mean(d)), float(np.std(d))
    fig, ax = plt.subplots(figsize=(8, 6.5), constrained_layout=True)
    x_um = 1e6 * (d - mean)
    ax.hist(x_um, bins=min(60, max(10, d.size // 20)), density=True, color="C0", alpha=0.7,
            label=f"{d.size} pairs")
    s_um = max(1e6 * std, 1e-9)
    g = np.linspace(x_um.min(), x_um.max(), 300)
    ax.plot(g, np.exp(-0.5 * (g / s_um) ** 2) / (s_um * np.sqrt(2 * np.pi)), "k", lw=1.2,
            label=f"Gaussian: σ = {s_um:.2f} µm")
    if track.distance_uncertainty_m is not None and track.valid.any():
        u_um = 1e6 * float(np.median(track.distance_uncertainty_m[track.valid]))
        ax.axvspan(-u_um, u_um, color="C1", alpha=0.12, lw=0,
                   label=f"expanded uncertainty (k = 2), the pairs' median: ±{u_um:.2f} µm")
    if true_distance_m is not None:
        ax.axvline(1e6 * (true_distance_m - mean), color="C3", ls="--",
                   label=f"truth ({1e6 * (mean - true_distance_m):+.1f} µm bias)")
    snr = track.sweep_snr_dechirped_db if track.sweep_snr_dechirped_db is not None else track.sweep_snr_db
    if snr is not None and snr.size and "bandwidth_hz" in track.attrs:
        points = int(track.attrs["points"])
        eta = eta_from_peak_snr(snr, points)
        bound_um = 1e6 * crb_pair_m(eta, points, float(track.attrs["bandwidth_hz"]),
                                    float(track.attrs.get("refractive_index", 1.0)))
        ax.plot(g, np.exp(-0.5 * (g / bound_um) ** 2) / (bound_um * np.sqrt(2 * np.pi)), color="C2", ls=":",
                lw=1.2, label=f"Cramér-Rao ({points} points, {10 * np.log10(eta):.1f} dB per point from the "
                              f"peaks): σ = {bound_um:.2f} µm, measured {s_um / bound_um:.2f}x")
    ax.set_xlabel(f"distance − {mean * 1e3:.4f} mm (µm)")
    ax.set_ylabel("probability density (1/µm)")
    ax.set_title(f"static target: mean {mean * 1e3:.4f} mm, standard deviation {s_um:.2f} µm")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=1)   # off the curves
    ax.grid(alpha=0.3)
    fig.savefig(path, dpi=120, format="png")
    plt.close(fig)
    return path


def echoes(track: Track, path: Path) -> Path:
    """Range-time picture of every echo of every half-sweep: those of the plain spectra
    (CFAR), and the target's own peaks de-chirped at its pair's velocity (a fast
    target's plain peak is smeared by its Doppler term below the CFAR's threshold), each
    coloured by its SNR; the valid pairs of the target and of every other object of the
    scene drawn over them, each in its own colour, and the persistent echoes (walls,
    windows) and the rival of the target named."""
    e = track.echoes
    fig, ax = plt.subplots(figsize=(9, 5.5), constrained_layout=True)
    own = track.sweep_distance_dechirped_m
    heard = (np.repeat(track.valid, 2) & np.isfinite(own)) if own is not None else np.zeros(0, bool)
    snrs = np.concatenate([e.snr_db, track.sweep_snr_dechirped_db[heard] if heard.any() else []])
    lo = float(np.percentile(snrs, 2)) if snrs.size else 0.0
    hi = float(snrs.max()) if snrs.size else 1.0
    sc = ax.scatter(1e3 * e.time_s, e.distance_m, c=e.snr_db, s=2, cmap="viridis", lw=0, vmin=lo, vmax=hi,
                    rasterized=True, label="echoes of the plain spectra (CFAR), coloured by SNR")
    if heard.any():
        ax.scatter(1e3 * track.sweep_time_s[heard], own[heard], c=track.sweep_snr_dechirped_db[heard], s=2,
                   marker="s", cmap="viridis", lw=0, vmin=lo, vmax=hi, rasterized=True,
                   zorder=3, label="the target's half-sweeps after the Doppler de-chirp (its distance then), "
                                   "coloured by SNR")
    fig.colorbar(sc, ax=ax, label="echo SNR over local noise (dB)")
    target = track.attrs.get("target_object")
    for k, o in enumerate(track.objects or []):        # every object in its own colour, the target red
        if o.id == target or not o.track.valid.any():
            continue
        d = np.where(o.track.valid, o.track.distance_m, np.nan)
        ax.plot(1e3 * o.track.time_s, d, color=f"C{4 + k % 6}", lw=1.0, zorder=2,
                label=f"object #{o.id} ({o.kind}, valid pairs)")
    d = np.where(track.valid, track.distance_m, np.nan)
    who = "tracked target" if target is None else f"target: object #{target}"
    ax.plot(1e3 * track.time_s, d, color="C3", lw=1.2, zorder=4, label=f"{who} (valid pairs)")
    p = e.persistent
    diffuse = p.get("diffuse", np.zeros(p["time_s"].size, bool))
    for mask, marker, label in ((~diffuse, "s", "persistent echoes (per 10 ms)"),
                                (diffuse, "D", "moving echo, smeared (energy centre)")):
        if mask.any():
            ax.plot(1e3 * p["time_s"][mask], p["distance_m"][mask], marker, ms=7, mfc="none", color="k",
                    label=label)
    rival = e.rival
    if rival is not None:
        ax.axhline(rival[0], color="C1", ls="--", lw=1,
                   label=f"rival: {rival[0]:.3f} m, {rival[1]:+.1f} dB over the target")
    for name, ls in (("min_range_m", ":"), ("max_range_m", "-.")):
        level = float(track.attrs.get(name, np.nan))
        if np.isfinite(level):
            ax.axhline(level, color="0.4", ls=ls, lw=0.8,
                       label=f"the target's band {'from' if name == 'min_range_m' else 'to'} {level:.3f} m")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("distance (m; plain echoes carry their Doppler shift)")
    ax.set_ylim(0, float(track.attrs.get("unambiguous_range_m", 0.5)))
    ax.set_title(f"every echo: {e.time_s.size} in the plain spectra of {track.sweep_time_s.size} "
                 f"half-sweeps, {int(heard.sum())} of the target de-chirped")
    legend = ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8)
    for handle in legend.legend_handles:           # the echoes' dots, big enough to see their kind
        if hasattr(handle, "set_sizes"):
            handle.set_sizes([16])
    ax.grid(alpha=0.3)
    fig.savefig(path, dpi=120, format="png")
    plt.close(fig)
    return path


def longest_stretch(track: Track) -> np.ndarray:
    """The pairs (indices) of the longest stretch of valid displacement, from its first
    valid pair to its last (gaps inside it included)."""
    s = track.displacement_stretch
    if s is None or not track.displacement_valid.any():
        return np.zeros(0, np.int64)
    ids, counts = np.unique(s[s >= 0], return_counts=True)
    mine = np.flatnonzero(s == ids[np.argmax(counts)])
    return np.arange(mine[0], mine[-1] + 1)


def displacement_spectrum(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies (Hz), amplitude spectral density (m/sqrt(Hz)) and line amplitude (m)
    of a displacement sampled at times `t` (uniform; NaN gaps filled linearly), its
    straight line taken off, under a Hann window."""
    ok = np.isfinite(x)
    x = np.interp(t, t[ok], x[ok])
    x = x - np.polyval(np.polyfit(t, x, 1), t)
    w = np.hanning(x.size)
    spec = np.fft.rfft(w * x)
    fs = 1.0 / float(np.median(np.diff(t)))
    return (np.fft.rfftfreq(x.size, 1.0 / fs), np.abs(spec) * np.sqrt(2.0 / (fs * np.sum(w * w))),
            2.0 * np.abs(spec) / np.sum(w))


def displacement(track: Track, path: Path, truth: Truth | None = None) -> Path:
    """The displacement from the phase over time, with its expanded uncertainty and the
    truth (and, with a truth, its error), and the amplitude spectrum of its longest
    stretch: its strongest line (m) and its floor (m/sqrt(Hz))."""
    from ..displacement import ZERO_PAIRS

    ok = track.displacement_valid
    t_ms = 1e3 * track.time_s
    x = np.where(ok, track.displacement_m, np.nan)
    most = np.nanmax(np.abs(x), initial=0)
    scale, unit = (1e9, "nm") if most < 2e-6 else (1e6, "µm") if most < 2e-3 else (1e3, "mm")
    known = truth is not None and ok.any()
    fig, axes = plt.subplots(3 if known else 2, 1, figsize=(9, 10 if known else 7.5), constrained_layout=True)
    ax, bx = axes[0], axes[-1]
    ax.plot(t_ms, scale * x, color="C0", lw=0.8, label="from the phase")
    u = np.where(ok, track.displacement_uncertainty_m, np.nan)
    ax.fill_between(t_ms, scale * (x - u), scale * (x + u), color="C0", alpha=0.2, lw=0,
                    label="expanded uncertainty (k = 2)")
    if known:
        r = truth_at(truth, track.time_s)[0]
        r = r - np.mean(r[np.flatnonzero(track.displacement_stretch == 0)[:ZERO_PAIRS]])    # the same zero
        ax.plot(t_ms, scale * r, color="k", lw=0.8, ls="--", label="truth")
        cx = axes[1]
        cx.plot(t_ms, 1e9 * (x - r), color="C3", lw=0.6, label="from the phase − truth")
        cx.fill_between(t_ms, -1e9 * u, 1e9 * u, color="C0", alpha=0.2, lw=0, label="± expanded uncertainty")
        cx.set_xlabel("time (ms)")
        cx.set_ylabel("error (nm)")
        cx.legend(fontsize=8, loc="best")
        cx.grid(alpha=0.3)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel(f"displacement ({unit})")
    stretches = int(track.attrs.get("displacement_stretches", 0))
    ax.set_title(f"{Path(str(track.attrs.get('source', ''))).name}: displacement from the beat's phase, "
                 f"{100 * ok.mean():.1f} % valid, {stretches} stretch{'es' if stretches != 1 else ''}")
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    run = longest_stretch(track)
    if run.size >= 64:
        f, asd, amp = displacement_spectrum(track.time_s[run], x[run])
        line = 1 + int(np.argmax(amp[1:]))
        floor = float(np.median(asd[1:]))
        bx.semilogy(f[1:] / 1e3, asd[1:], color="C0", lw=0.8)
        bx.axhline(floor, color="C2", ls=":", label=f"median floor {floor:.3g} m/√Hz")
        bx.plot(f[line] / 1e3, asd[line], "o", mfc="none", color="C3",
                label=f"strongest line: {f[line]:.0f} Hz, amplitude {amp[line]:.3g} m")
        span_ms = 1e3 * (track.time_s[run[-1]] - track.time_s[run[0]])
        bx.set_title(f"amplitude spectrum of the longest stretch ({span_ms:.1f} ms, its straight line "
                     "taken off, Hann window)")
        bx.legend(fontsize=8, loc="best")
    else:
        bx.text(0.5, 0.5, "no stretch of 64 pairs for a spectrum", transform=bx.transAxes, ha="center",
                va="center", color="0.4")
    bx.set_xlabel("frequency (kHz)")
    bx.set_ylabel("amplitude spectral density (m/√Hz)")
    bx.grid(alpha=0.3, which="both")
    fig.savefig(path, dpi=120, format="png")
    plt.close(fig)
    return path
