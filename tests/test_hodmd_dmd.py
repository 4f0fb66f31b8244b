"""HODMD (parastokes.parareal.dmd) against closed forms and against PyDMD's HODMD."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from parastokes.parareal.dmd import hodmd, retained_rank

X = np.linspace(0.0, 1.0, 40)
DT = 0.1
WINDOW = np.arange(40) * DT  # snapshots over [0, 3.9]
FAR = np.linspace(4.0, 20.0, 9)  # up to five windows beyond the last snapshot


def oscillations(t: np.ndarray) -> np.ndarray:
    """A damped and a growing oscillation and a decay: 5 Koopman modes (δ = -0.3 ± 2i,
    0.1 ± 3.1i, -0.05) on only 3 spatial shapes, so the snapshot matrix has rank 3."""
    t = np.atleast_1d(t)
    return (np.outer(np.sin(np.pi * X), np.exp(-0.3 * t) * np.cos(2.0 * t))
            + np.outer(X**2, np.exp(0.1 * t) * np.sin(3.1 * t))
            + np.outer(np.cos(3 * X), np.exp(-0.05 * t)))


def relative_error(approx: np.ndarray, exact: np.ndarray) -> float:
    return float(np.abs(approx - exact).max() / np.abs(exact).max())


@pytest.mark.parametrize("d", [2, 3, 5, 10, 20])
def test_damped_and_growing_oscillations_extrapolate_to_round_off_for_every_d_that_suffices(d):
    """Rank 3 < 5 modes: any d >= 2 (d·3 >= 5) recovers the exact rates and extrapolates five
    windows ahead (where the growing mode has grown e^{1.6}) to round-off (measured <= 3e-13)."""
    found = hodmd(oscillations(WINDOW), d, dt=DT, svd_tolerance=1e-12, amplitude_tolerance=1e-12)
    expected = np.sort_complex(np.array([-0.3 + 2j, -0.3 - 2j, 0.1 + 3.1j, 0.1 - 3.1j, -0.05]))
    rates = np.sort_complex(found.growth_rates + 1j * found.frequencies)
    assert rates == pytest.approx(expected, abs=1e-9)
    assert relative_error(found.reconstruct(FAR), oscillations(FAR)) < 1e-11


def test_d_equal_one_is_dmd_and_cannot_find_more_modes_than_the_rank():
    found = hodmd(oscillations(WINDOW), 1, dt=DT, svd_tolerance=1e-12, amplitude_tolerance=1e-12)
    assert len(found.growth_rates) == 3
    assert relative_error(found.reconstruct(FAR), oscillations(FAR)) > 0.1  # measured 0.9


def test_a_standing_wave_needs_two_delayed_copies():
    """cos(2t) sin(πx) has rank 1 but two modes e^{±2it}: d = 1 fails, d >= 2 is exact."""
    def wave(t):
        return np.outer(np.sin(np.pi * X), np.cos(2.0 * np.atleast_1d(t)))

    errors = {
        d: relative_error(hodmd(wave(WINDOW), d, dt=DT, svd_tolerance=1e-12,
                                amplitude_tolerance=1e-12).reconstruct(FAR), wave(FAR))
        for d in (1, 2, 3)
    }
    assert errors[1] > 0.5  # measured 0.96
    assert errors[2] < 1e-11 and errors[3] < 1e-11


def test_reconstruction_at_a_scalar_time_is_a_real_column_and_starts_at_t0():
    found = hodmd(oscillations(WINDOW + 7.0), 4, dt=DT, t0=7.0, svd_tolerance=1e-12,
                  amplitude_tolerance=1e-12)
    value = found.reconstruct(7.0 + 1.25)
    assert value.shape == (40,) and value.dtype == float
    assert relative_error(value, oscillations(8.25)[:, 0]) < 1e-11


def test_the_tolerances_truncate_as_documented():
    sigma = np.array([1.0, 1e-3, 1e-9])
    assert retained_rank(sigma, 1e-8) == 2  # ‖(1e-9)‖/‖σ‖ = 1e-9 <= 1e-8
    assert retained_rank(sigma, 1e-10) == 3
    assert retained_rank(np.zeros(3), 1e-8) == 0
    # a mode below ε times the largest amplitude is dropped: the decay has amplitude ~1e-9
    small = np.outer(np.sin(np.pi * X), np.cos(2.0 * WINDOW)) + 1e-9 * np.outer(X, np.exp(-WINDOW))
    kept = hodmd(small, 3, dt=DT, svd_tolerance=1e-14, amplitude_tolerance=1e-6)
    assert len(kept.growth_rates) == 2
    assert len(hodmd(small, 3, dt=DT, svd_tolerance=1e-14, amplitude_tolerance=1e-12)
               .growth_rates) == 3
    # a zero snapshot matrix (no difference to extrapolate) gives zero everywhere
    assert not hodmd(np.zeros((5, 12)), 3).reconstruct(FAR).any()


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="at least 11 snapshots"):
        hodmd(np.ones((3, 10)), 10)
    with pytest.raises(ValueError, match="d must be an integer >= 1"):
        hodmd(np.ones((3, 10)), 0)
    with pytest.raises(ValueError, match="svd_tolerance"):
        hodmd(np.ones((3, 10)), 2, svd_tolerance=1.5)


@pytest.mark.parametrize("d", [2, 5, 10])
def test_agrees_with_pydmd_hodmd(d):
    """PyDMD's HODMD (rank 5 kept in both of its SVDs, least-squares amplitudes over all
    snapshots: opt=True) finds the same eigenvalues and the same reconstruction."""
    pydmd = pytest.importorskip("pydmd")
    data = oscillations(WINDOW)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # PyDMD warns about the rank-deficient data
        ref = pydmd.HODMD(svd_rank=5, svd_rank_extra=5, exact=True, opt=True, d=d).fit(data)
        ref.dmd_time["tend"] = 199  # reconstruct over five windows
        extended = ref.reconstructed_data.real
    ours = hodmd(data, d, dt=DT, svd_tolerance=1e-12, amplitude_tolerance=1e-12)
    assert np.sort_complex(ours.eigenvalues) == pytest.approx(np.sort_complex(ref.eigs),
                                                              abs=1e-10)
    times = np.arange(200) * DT
    assert relative_error(ours.reconstruct(times), extended) < 1e-10


def test_a_weak_growing_mode_is_fitted_despite_its_huge_column():
    """A mode of amplitude 1e-12 growing as e^{0.6 t} is invisible in the window but dominates at
    t = 40-50: the amplitudes' least squares is solved with equilibrated columns, so the decaying
    modes are not lost in the growing mode's round-off (without: 5e-7 at t = 50, measured; on the
    authors' rod such a fit returned amplitudes of 1e-33 and extrapolated to 5e9)."""
    def signal(t):
        t = np.atleast_1d(t)
        return (np.outer(np.sin(np.pi * X), np.exp(-0.3 * t) * np.cos(2 * t))
                + np.outer(X**2, np.exp(-0.1 * t) * np.sin(3.1 * t))
                + 1e-12 * np.outer(np.cos(3 * X), np.exp(0.6 * t)))

    times = np.arange(66) * 0.5
    fit = hodmd(signal(times), 6, dt=0.5, svd_tolerance=1e-14, amplitude_tolerance=1e-14)
    far = np.array([40.0, 50.0])
    assert relative_error(fit.reconstruct(far), signal(far)) < 1e-10  # measured 1.5e-12
