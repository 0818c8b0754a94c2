"""`fmcw-cl report`: events against /truth, the pictures, and the spectra's physics."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from fmcw_cl.capture import Capture
from fmcw_cl.evaluate import truth_at
from fmcw_cl.report import make_report
from fmcw_cl.report.events import find_events
from fmcw_cl.report.spectra import stretch_spectra
from fmcw_cl.track import read_track

ROOT = Path(__file__).parents[1]


def exact_extremum(truth, t0, t1, quantity, sign):
    """(time, value) of the true extremum in [t0, t1] on a 1 us grid, independent of
    the event finder."""
    g = np.arange(t0, t1, 1e-6)
    y = truth_at(truth, g)[("distance_m", "velocity_mps", "acceleration_mps2").index(quantity)]
    i = np.argmax(sign * y)
    return g[i], y[i]


@pytest.fixture(scope="module")
def jump_report(tmp_path_factory, jump_track):
    out = tmp_path_factory.mktemp("report")
    return out, make_report(jump_track, out)


@pytest.mark.parametrize("kind,quantity,window,sign", [
    ("velocity_peak", "velocity_mps", (0.05, 0.10), 1),            # leg protraction, 7.15 m/s
    ("acceleration_valley", "acceleration_mps2", (0.08, 0.10), -1),  # takeoff, -361 m/s^2
    ("impact", "acceleration_mps2", (0.18, 0.21), 1),              # landing, 300 m/s^2
])
def test_jump_events_match_truth(jump_report, jump_capture, kind, quantity, window, sign):
    _, got = jump_report
    with Capture(jump_capture) as cap:
        truth = cap.truth()
    t_true, v_true = exact_extremum(truth, *window, quantity, sign)
    found = [e for e in got["events"] if e["kind"] == kind and window[0] <= e["time_s"] <= window[1]]
    assert len(found) == 1
    e = found[0]
    assert abs(e["time_s"] - t_true) <= 0.5e-3
    assert abs(e["value"] - v_true) <= 0.01 * abs(v_true)
    assert e["true_time_s"] is not None and abs(e["time_error_s"]) <= 0.5e-3


def test_jump_report_files(jump_report):
    out, got = jump_report
    names = {p.rsplit("/", 1)[-1] for p in got["written"]}
    assert names == {"kinematics.png", "echoes.png", "spectra.png", "displacement.png", "events.md",
                     "events.json", "uncertainty.md"}  # moving
    for name in ("kinematics.png", "echoes.png", "spectra.png", "displacement.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.glob("*.part"))
    table = json.loads((out / "events.json").read_text())
    assert [e["kind"] for e in table["events"]].count("impact") == 2   # the strike and the bounce
    md = (out / "events.md").read_text()
    assert "| impact |" in md and "time error (ms)" in md


def test_static_report_has_precision_and_no_events(tmp_path, static_capture):
    from fmcw_cl.engine import process
    from fmcw_cl.track import write_track

    track_file = write_track(tmp_path / "s.track.h5", process(static_capture))
    got = make_report(track_file, tmp_path / "rep")
    assert any(p.endswith("precision.png") for p in got["written"])
    assert got["events"] == []


def test_noise_makes_no_events():
    rng = np.random.default_rng(0)
    t = np.arange(4000) * 50e-6
    events = find_events(t, 0.3 + 3e-6 * rng.standard_normal(t.size), 4e-4 * rng.standard_normal(t.size),
                         0.3 * rng.standard_normal(t.size))
    assert events == []


def test_no_event_at_the_datas_edge_or_at_a_gap():
    """A take-off cut off while the foot still rises has its largest distance at its
    last pair: not an apex; an extremum within half the acceleration's window of a gap
    is not an event either (its extremum may lie in the gap); one well inside a run is."""
    t = np.arange(2000) * 50e-6
    rising = 0.07 + 2.0 * t ** 2                          # accelerating away to the last pair
    assert find_events(t, rising, 4.0 * t, np.full(t.size, 4.0)) == []
    hump = 0.2 - 8.0 * (t - 0.05) ** 2                    # an apex at 50 ms, velocity 0 there
    events = find_events(t, hump, -16.0 * (t - 0.05), np.full(t.size, -16.0))
    assert [(e.kind, round(e.time_s, 4)) for e in events] == [("apex", 0.05)]
    gap = (t > 0.0503) & (t < 0.06)                       # data missing from 0.3 ms after the apex
    cut = [np.where(gap, np.nan, x) for x in (hump, -16.0 * (t - 0.05), np.full(t.size, -16.0))]
    assert find_events(t, *cut) == []


def test_at_rest_only_where_the_verified_velocity_says_so(tmp_path):
    """The shipped sample of a foot moving at 3.6-6.3 m/s has no event in its 8 ms: the
    table says that no extremum lies in the data, not that the target is at rest."""
    from fmcw_cl.engine import process
    from fmcw_cl.track import write_track

    for name, said in (("jump_wall_fading", "no extremum inside the verified stretches"),
                       ("static_0p3m", "the target is at rest")):
        track = process(ROOT / "data_samples" / f"{name}.h5")
        make_report(write_track(tmp_path / f"{name}.track.h5", track), tmp_path / name)
        assert f"| (none: {said}) |" in (tmp_path / name / "events.md").read_text()


def test_correction_sharpens_the_spectrum(jump_capture, jump_track):
    """Near the apex (0.3 m) the corrected peak is narrow and where the track says; the
    plain FFT's is smeared over many bins (the paper's Fig. 5 against 6a)."""
    track = read_track(jump_track)
    sp = stretch_spectra(jump_capture, 0.134, 0.136, 1000, float(track.attrs["sync_delay_samples"]))
    i = sp.distance_m.searchsorted(0.05)

    def width(axis, db):
        return np.ptp(axis[np.flatnonzero(db >= -6)])   # extent above -6 dB (m)

    for row in range(sp.time_s.size):
        assert width(sp.distance_m[i:], sp.corrected_db[row, i:]) < 5e-3   # Hann: ~2 resolution cells
        assert width(sp.raw_distance_m, sp.raw_db[row]) > 30e-3
    # each peak is where the track's half-sweep distance (with its Doppler shift) says
    k = np.searchsorted(track.sweep_time_s, sp.time_s - 1e-6)
    assert np.allclose(track.sweep_time_s[k], sp.time_s, atol=1e-7)
    peak = sp.distance_m[i + np.argmax(sp.corrected_db[:, i:], axis=1)]
    assert np.all(np.abs(peak - track.sweep_distance_m[k]) < 0.5e-3)   # a bin is 0.46 mm


def test_track_without_echoes_still_reports(tmp_path, static_capture):
    """A track written before /echoes existed (or by another writer): no echo picture."""
    from fmcw_cl.engine import process
    from fmcw_cl.track import write_track

    track = process(static_capture)
    track.echoes = None
    got = make_report(write_track(tmp_path / "old.track.h5", track), tmp_path / "rep")
    assert not any(p.endswith("echoes.png") for p in got["written"])


def test_cramer_rao_bound_of_a_pair():
    """The N-point bound at 0 dB per point, N = 1000, B = 160 GHz: 11.6 um a pair (the
    precision benchmark's table), and the SNR a Hann-windowed peak shows: eta N / 3."""
    from fmcw_cl.evaluate import crb_pair_m, eta_from_peak_snr

    assert crb_pair_m(1.0, 1000, 160e9) == pytest.approx(11.6e-6, rel=0.01)
    assert crb_pair_m(10.0, 1000, 160e9) == pytest.approx(11.6e-6 / np.sqrt(10), rel=0.01)
    assert eta_from_peak_snr([10 * np.log10(1000 / 3)] * 3, 1000) == pytest.approx(1.0)


def test_a_still_targets_axes_read_plain_numbers(tmp_path, static_capture, monkeypatch):
    """A static target's distance varies by microns: its axis reads microns about its
    distance in mm (not 0.250006 m, nor an offset label such as 1e-5+2.5e-1), its
    velocity mm/s; no acceleration within half a window of a run's ends (the quadratic's
    extrapolation: -0.6 m/s^2 at a still target's first pair)."""
    from fmcw_cl.engine import process
    from fmcw_cl.report import figures
    from fmcw_cl.stages.kinematics import WINDOW_PAIRS

    figs = []
    monkeypatch.setattr(figures.plt, "close", figs.append)
    track = process(static_capture)
    figures.kinematics(track, tmp_path / "k.png")
    (fig,) = figs
    fig.canvas.draw()
    assert [ax.yaxis.get_major_formatter().get_offset() for ax in fig.axes] == ["", "", ""]
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert re.fullmatch(r"distance − 2[45]\d\.\d\d0 mm \(µm\)", labels[0]), labels
    assert labels[1:] == ["velocity (mm/s)", "acceleration (m/s²)"]
    distance = fig.axes[0].lines[0].get_ydata()
    assert np.nanmax(np.abs(distance)) < 20                 # microns
    acc = fig.axes[2].lines[0].get_ydata()
    half = WINDOW_PAIRS // 2
    assert track.valid.all() and np.isnan(acc[:half]).all() and np.isnan(acc[-half:]).all()
    assert np.isfinite(acc[half:-half]).all()


def test_the_pictures_show_what_they_name(tmp_path, jump_track, monkeypatch):
    """The echoes picture holds the target's de-chirped half-sweeps (a fast target's
    plain peak is below the CFAR's threshold) with a legend entry for each kind of dot;
    the precision legend lies off the curves; the spectra name what lies below
    --min-range."""
    from fmcw_cl.report import figures

    track = read_track(jump_track)
    figs = []
    monkeypatch.setattr(figures.plt, "close", figs.append)
    figures.echoes(track, tmp_path / "e.png")
    ax = figs[-1].axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("plain spectra" in x for x in labels) and any("de-chirp" in x for x in labels)
    own = [c for c in ax.collections if "de-chirp" in str(c.get_label())]
    assert own and len(own[0].get_offsets()) == 2 * int(track.valid.sum())
    sp = stretch_spectra(track.attrs["source"], 0.13, 0.14, int(track.attrs["points"]),
                         float(track.attrs["sync_delay_samples"]), 0.03, track.chirp)
    figures.spectra(sp, tmp_path / "s.png", 10, float(track.attrs["unambiguous_range_m"]), 0.03)
    texts = [t.get_text() for t in figs[-1].axes[-1].texts]
    assert any("below --min-range (30 mm)" in t and "at 12 mm" in t for t in texts), texts
