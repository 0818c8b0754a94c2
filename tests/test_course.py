"""A band per pair along an object's course (fmcw_cl.course, Search.bands): the numpy
peak search, every kernel that searches a peak against it, the tracker on both
backends, and a capture converted along a course."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import bent_lut

from fmcw_cl.course import MIN_BINS, Course, searched
from fmcw_cl.stages import doppler, integrate, pairing
from fmcw_cl.stages.spectrum import Search, find_peaks


@pytest.fixture(scope="module")
def backend():
    from fmcw_cl.opencl.processor import OpenCLProcessor

    return OpenCLProcessor()


def _bands(rng, pairs: int, half: int, lo: int = 3) -> np.ndarray:
    """Random (2, pairs, 2) bands inside [lo, half): narrow, wide, one of MIN_BINS, the
    whole search, ends inside and on the edges of blocks of eight bins."""
    a = rng.integers(lo, half - 64, (2, pairs))
    w = rng.choice([MIN_BINS, 7, 8, 9, 40, 150, 600], (2, pairs))
    b = np.minimum(a + w, half)
    out = np.stack([a, b], axis=-1).astype(np.int32)
    out[:, ::7] = (lo, half)
    return out


def test_each_rows_own_band_is_searched_as_that_row_alone():
    """find_peaks with a band per row against find_peaks of each row alone with its
    band: the arg-max (a peak just outside the band, ties), the floor, a band narrower
    than the guard."""
    rng = np.random.default_rng(1)
    half, rows = 1024, 60
    power = rng.exponential(1.0, (rows, half)) * 50
    bands = _bands(rng, rows, half)[0]
    power[np.arange(rows), np.minimum(bands[:, 1], half - 1)] = 1e6    # just past the band's top
    power[np.arange(rows), np.maximum(bands[:, 0] - 1, 0)] = 1e6        # just before its start
    power[5, bands[5, 0]: bands[5, 0] + 2] = 1e5                       # a tie: the lower bin
    got = find_peaks(power, bands[:, 0], bands[:, 1])
    for i in range(rows):
        want = find_peaks(power[i: i + 1], int(bands[i, 0]), int(bands[i, 1]))
        np.testing.assert_allclose(got.bin[i], want.bin[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.snr_db[i], want.snr_db[0], rtol=1e-6)
        assert bands[i, 0] - 0.5 <= got.bin[i] <= bands[i, 1] - 0.5
    assert round(got.bin[5]) == bands[5, 0]
    # the same band for every row: find_peaks's
    same = find_peaks(power, np.full(rows, 40), np.full(rows, 900))
    np.testing.assert_allclose(same.bin, find_peaks(power, 40, 900).bin, atol=1e-12)
    np.testing.assert_allclose(same.snr_db, find_peaks(power, 40, 900).snr_db, rtol=1e-6)


def test_a_course_gives_each_pair_its_band_inside_the_search():
    """Course.bands: each direction at its own half-sweep's time, interpolated, rounded
    outwards, clipped into the search with at least MIN_BINS; the search's band before
    and after the course."""
    mpb = 1e-3
    course = Course(np.array([0.0, 1.0]), np.array([[0.1004, 0.2004], [0.1204, 0.2204]]),
                    np.array([[0.1104, 0.2104], [0.1304, 0.5004]]))
    search = Search(50, 400)
    t = np.array([-0.5, 0.0, 0.5, 1.0, 1.5])
    got = course.bands(t, t + 0.25, search, mpb)
    assert got.dtype == np.int32 and got.shape == (2, 5, 2)
    np.testing.assert_array_equal(got[0, :, 0], [50, 100, 150, 200, 50])
    np.testing.assert_array_equal(got[0, :, 1], [400, 112, 162, 212, 400])     # the top bin held whole
    np.testing.assert_array_equal(got[1], [[50, 400], [145, 224], [195, 400], [50, 400], [50, 400]])
    narrow = Course(np.array([0.0, 1.0]), np.full((2, 2), 0.398), np.full((2, 2), 0.398))
    b = narrow.bands(np.array([0.5]), np.array([0.5]), search, mpb)
    assert b[0, 0].tolist() == [396, 400] and b[0, 0, 1] - b[0, 0, 0] >= MIN_BINS
    assert searched(search, None, t, t, mpb) is search


STILL_M = 0.07


def _two_echoes(pairs: int, seed: int, weak: float = 0.3, speed: tuple = (0.4, 1.2),
                still_m: float = STILL_M, start_m: float = 0.15):
    """Resampled rows of a strong still echo at `still_m` and a weaker one moving from
    `start_m` at `speed` (m/s, from and to; by default 0.4 -> 1.2, its plain peaks
    Doppler-shifted by 11-33 mm), under noise; the times, model, search and the mover's
    distance and velocity per pair. At STILL_M the still echo lies beyond the mover's
    bands (`_course_of`) in its plain spectra and in those de-chirped at the mover's
    velocities (its de-chirped image moves by -k v)."""
    from fmcw_cl.physics import C

    rng = np.random.default_rng(seed)
    lut, win = bent_lut()
    half_s = 25e-6
    model = doppler.doppler_model(lut, half_s, 1024, win)
    t_mid = 0.01 + np.arange(pairs) * 50e-6
    v = np.linspace(*speed, pairs)
    r = start_m + np.cumsum(v) * 50e-6
    rows = []
    for beta, dt in ((model.beta_rise, -half_s / 2), (model.beta_fall, half_s / 2)):
        mover = np.outer(2 * (r + v * dt) / C, lut.nu_hz) + v[:, None] * beta + rng.uniform(0, 1, (pairs, 1))
        still = np.outer(np.full(pairs, 2 * still_m / C), lut.nu_hz) + rng.uniform(0, 1, (pairs, 1))
        noise = rng.normal(0, 0.3, (pairs, lut.points))
        x = weak * np.cos(2 * np.pi * mover) + np.cos(2 * np.pi * still) + noise
        rows.append(((x - x.mean(axis=1, keepdims=True)) * win).astype(np.float32))
    times = pairing.Times(t_mid - half_s / 2, t_mid + half_s / 2)
    search = Search(int(0.03 / model.metres_per_bin), model.nfft // 2, echoes=True)
    return rows, times, model, search, r, v


def _course_of(times, model, r, v, width_m: float = 0.012, seeded: bool = False) -> Course:
    """The mover's course: in each direction from its distance to its plain peak (the
    distance shifted by k v: the tracker's first pass; the de-chirped peaks lie at the
    distance) +- width_m, over the pairs' whole half-sweeps; `seeded`: with its
    velocity (the first pass de-chirped at it)."""
    t = np.r_[times.rise[0], times.mid, times.fall[-1]]
    r, v = np.r_[r[0], r, r[-1]], np.r_[v[0], v, v[-1]]
    shifted = np.stack([r + model.k_rise * v, r + model.k_fall * v])
    return Course(t, np.minimum(shifted, r) - width_m, np.maximum(shifted, r) + width_m,
                  v if seeded else None)


def test_banded_spectrum_kernel_matches_numpy(backend, kernel_variant):
    """spectrum_peak / spectrum_lanes with each direction's rows in bands of their own
    (narrow, wide, idle lanes, both directions a launch): plain with every echo listed
    (the echoes do not depend on the bands) and de-chirped at picked rows (a row's band
    by its index), against doppler.measure; unbanded rows of the same launch unchanged."""
    from fmcw_cl.opencl import spectrum as k_spectrum

    rows, times, model, search, r, v = _two_echoes(77, 3)
    rng = np.random.default_rng(4)
    search = replace(search, bands=_bands(rng, 77, model.nfft // 2, search.lo))
    d_rows = [k_spectrum.as_device(backend.bufs, x) for x in rows]
    betas = (model.beta_rise, model.beta_fall)
    plain = backend.measure_each(d_rows, betas, None, model, search)
    pick = np.sort(rng.choice(77, 30, replace=False))
    vel = rng.uniform(-5, 5, 30)
    picked = backend.measure_each(d_rows, betas, vel, model, replace(search, echoes=False), pick)
    unbanded = backend.measure_each(d_rows, betas, None, model, replace(search, bands=None))
    for j in range(2):
        want = doppler.measure(rows[j].astype(np.float64), None, None, model, search, direction=j)
        np.testing.assert_allclose(plain[j][0], want[0], atol=2e-3 * model.metres_per_bin)
        np.testing.assert_allclose(plain[j][1], want[1], atol=2e-2)
        np.testing.assert_array_equal(plain[j][2].count, unbanded[j][2].count)
        np.testing.assert_array_equal(plain[j][2].bin, unbanded[j][2].bin)
        want = doppler.measure(rows[j].astype(np.float64), betas[j], vel, model, search, pick, direction=j)
        np.testing.assert_allclose(picked[j][0], want[0], atol=2e-3 * model.metres_per_bin)
        np.testing.assert_allclose(picked[j][1], want[1], atol=2e-2)
        lo, hi = search.band(j, pick)
        assert np.all((picked[j][0] / model.metres_per_bin >= lo - 0.5) & (picked[j][0] / model.metres_per_bin
                                                                              <= hi - 0.5))
        # one direction alone takes that direction's bands
        alone = backend.measure(d_rows[j], betas[j], vel, model, replace(search, echoes=False), pick, j)
        np.testing.assert_array_equal(alone[0], picked[j][0])
    # the bands moved peaks: a static search finds others
    assert np.mean(np.abs(plain[0][0] - unbanded[0][0]) > model.metres_per_bin) > 0.3


def test_banded_integration_kernel_matches_numpy(backend, kernel_variant):
    """integrate_peak / integrate_lanes with a band per row: against integrate.peaks."""
    from fmcw_cl.opencl import integrate as k_integrate
    from fmcw_cl.opencl.buffers import DeviceRows
    from fmcw_cl.opencl.context import cl

    rng = np.random.default_rng(5)
    rows, half = 45, 1024
    power = rng.exponential(1.0, (rows, half)) * 1e3
    power[:, half // 3] += 5e5
    power[:, half // 2] += 2e5
    disp = np.cumsum(rng.normal(0.0, 3.0, rows))
    search = Search(3, half - 2, bands=_bands(rng, rows, half - 2))
    store = DeviceRows(backend.bufs, rows, half)
    cl.enqueue_copy(backend.rt.queue, store.buffer, power.astype(np.float32))
    for j in range(2):
        got = k_integrate.peaks(backend.rt, backend.bufs, store, disp, 5, search, None, j)
        want = integrate.peaks(power, disp, 5, search, None, j)
        np.testing.assert_array_equal(got[2], want[2])
        np.testing.assert_allclose(got[0], want[0], atol=2e-3)
        np.testing.assert_allclose(got[1], want[1], atol=2e-3)
        lo, hi = search.band(j)
        assert np.all((got[0] >= lo - 0.5) & (got[0] <= hi - 0.5))
    assert not np.allclose(integrate.peaks(power, disp, 5, search, None, 0)[0],
                           integrate.peaks(power, disp, 5, replace(search, bands=None))[0])


@pytest.mark.parametrize("k, seeded", [(1, False), (4, False), (1, True), (4, True)])
def test_banded_tracker_passes_on_the_device_equal_the_host_passes(backend, kernel_variant, k,
                                                                  seeded):
    """kernels/track.cl's passes (and with integration, integrate.cl's) along a course
    (`seeded`: its first pass de-chirped at the course's velocity) against pairing.passes
    driven by the same device's measurements in the same bands."""
    from fmcw_cl import spectrum_ops
    from fmcw_cl.opencl import spectrum as k_spectrum

    rows, times, model, search, r, v = _fast_by_a_still_echo(6) if seeded else _two_echoes(301, 6, weak=0.15)
    course = _course_of(times, model, r, v, seeded=seeded)
    search = searched(search, course, times.rise, times.fall, model.metres_per_bin)
    assert (search.velocity is not None) == seeded
    d_rows = tuple(k_spectrum.as_device(backend.bufs, x) for x in rows)
    if k == 1:
        first, state = backend.track(d_rows, times, model, search, 6, True)
        want_first, want = spectrum_ops.SpectrumOps.track(backend, d_rows, times, model, search, 6, True)
        for a, b in zip(first, want_first, strict=True):
            np.testing.assert_array_equal(a[0], b[0])
    else:
        search = replace(search, echoes=False)
        state = backend.integrated(d_rows, times, model, search, 6, k)
        want = spectrum_ops.SpectrumOps.integrated(backend, d_rows, times, model, search, 6, k)
    for key in ("d_r", "s_r", "d_f", "s_f", "vd", "count"):
        np.testing.assert_array_equal(getattr(state, key), getattr(want, key), err_msg=key)
    np.testing.assert_array_equal(state.verdict[0], pairing.verdict(want, times, model)[0])
    if seeded:          # the first pass at the course's velocities: the mover converged there
        assert np.mean(state.verdict[0]) > 0.9


@pytest.mark.parametrize("seed", [7, 8, 9])
def test_a_course_holds_the_weaker_of_two_echoes(backend, seed):
    """A mover 10 dB weaker than a still echo in the same band: the tracker holds the
    still echo in nearly every pair; along the mover's course (+-12 mm) it holds the
    mover, within 0.5 mm, in 95 % of the pairs, on numpy and on the device alike (the
    same valid pairs)."""
    rows, times, model, search, r, v = _two_echoes(400, seed)
    plain = pairing.track_pairs(rows[0].astype(np.float64), rows[1].astype(np.float64), times, model, search)
    assert np.mean(np.abs(plain.distance - STILL_M) < 1e-3) > 0.8
    along = searched(search, _course_of(times, model, r, v), times.rise, times.fall, model.metres_per_bin)
    got = pairing.track_pairs(rows[0].astype(np.float64), rows[1].astype(np.float64), times, model, along)
    assert np.all(along.bands[..., 0] * model.metres_per_bin > STILL_M + 0.03)
    assert np.mean(got.valid & (np.abs(got.distance - r) < 5e-4)) > 0.95
    assert not np.any(got.valid & (np.abs(got.distance - r) > 2e-3))
    _device_agrees(backend, rows, times, model, along, got)


def _device_agrees(backend, rows, times, model, search, got) -> None:
    """The tracker on the device (`backend`) gives numpy's `got` along `search`: the same
    valid pairs (99 %), their distances within 20 um (float32 spectra)."""
    from fmcw_cl.opencl import spectrum as k_spectrum

    d_rows = tuple(k_spectrum.as_device(backend.bufs, x) for x in rows)
    dev = pairing.track_pairs(*d_rows, times, model, search, ops=backend)
    assert np.mean(dev.valid == got.valid) > 0.99
    np.testing.assert_allclose(dev.distance[dev.valid & got.valid], got.distance[dev.valid & got.valid],
                               atol=2e-5)


def _fast_by_a_still_echo(seed: int):
    """`_two_echoes`: a mover at 2 -> 2.5 m/s from 0.10 m, 6 dB weaker than a still echo
    at 0.14 m, between its distance and its rising plain peak (k v = 55-68 mm; the test
    table's range ends at 0.234 m: both plain peaks inside it)."""
    return _two_echoes(200, seed, weak=0.5, speed=(2.0, 2.5), still_m=0.14, start_m=0.10)


@pytest.mark.parametrize("seed", [6, 7, 8, 9])
def test_a_fast_mover_along_its_course_is_first_measured_at_its_velocity(backend, seed):
    """`_fast_by_a_still_echo`: in its course's band the tracker's plain first pass holds
    the still echo in the rising half-sweeps (the mover's plain peak smeared by its
    chirp), and a third of its pairs end off the mover, dozens of the tracker's valid ones
    more than 2 mm off; de-chirped first at the course's velocity (Course.v_mps,
    Search.velocity: the mover sharp, the still echo smeared) 95 % of its pairs are valid
    within 0.5 mm and none 2 mm off, on numpy and on the device alike."""
    rows, times, model, search, r, v = _fast_by_a_still_echo(seed)
    x = tuple(a.astype(np.float64) for a in rows)
    plain = searched(search, _course_of(times, model, r, v), times.rise, times.fall, model.metres_per_bin)
    lo, hi = plain.band(0)
    assert np.all((lo * model.metres_per_bin < 0.14) & (hi * model.metres_per_bin > 0.14))
    unseeded = pairing.track_pairs(*x, times, model, plain)
    assert np.mean(unseeded.valid & (np.abs(unseeded.distance - r) < 5e-4)) < 0.8
    assert np.sum(unseeded.valid & (np.abs(unseeded.distance - r) > 2e-3)) > 20
    seeded = searched(search, _course_of(times, model, r, v, seeded=True), times.rise, times.fall,
                      model.metres_per_bin)
    np.testing.assert_allclose(seeded.velocity, v, atol=1e-6)
    got = pairing.track_pairs(*x, times, model, seeded)
    assert np.mean(got.valid & (np.abs(got.distance - r) < 5e-4)) > 0.95
    assert not np.any(got.valid & (np.abs(got.distance - r) > 2e-3))
    _device_agrees(backend, rows, times, model, seeded, got)


def test_a_course_velocity_is_each_pairs_first_de_chirp_where_known():
    """Course.velocities: interpolated at the pairs' centres in float32 values; 0 beyond
    the course's times and between two times where either is unknown (0)."""
    course = Course(np.array([0.0, 1.0, 2.0, 3.0]), np.zeros((2, 4)), np.ones((2, 4)),
                    np.array([1.0, 2.0, 0.0, 4.0]))
    got = course.velocities(np.array([-0.5, 0.0, 0.5, 0.1, 1.5, 2.5, 3.0, 3.5]))
    np.testing.assert_array_equal(got, np.float32([0, 1, 1.5, 1.1, 0, 0, 4, 0]).astype(np.float64))
    assert Course(course.t_s, course.lo_m, course.hi_m).velocities(np.zeros(3)) is None
