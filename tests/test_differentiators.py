"""Check W1: closed-form differentiators (Westwick & Perreault 2012, eqs. 10-13) = inverse DFT."""
import numpy as np
import pytest

from jointbench.core import differentiators as d


@pytest.mark.parametrize("N", [16, 256, 1000])
@pytest.mark.parametrize("fs", [50.0, 500.0])
def test_closed_forms_equal_idft(N, fs):
    for order, closed in ((1, d.h1(N, fs)), (2, d.h2(N, fs))):
        ref = d.idft_derivative(N, fs, order)
        assert np.max(np.abs(closed - ref)) <= 1e-9 * np.max(np.abs(ref))
    assert np.array_equal(d.h0(N), d.idft_derivative(N, fs, 0).round(12))


def test_symmetry_h1_odd_h2_even():
    N, fs = 256, 500.0
    lags, a = d.two_sided(d.h1(N, fs), 100, 100)
    np.testing.assert_allclose(a, -a[::-1], rtol=0, atol=1e-9 * abs(a).max())
    lags, b = d.two_sided(d.h2(N, fs), 100, 100)
    np.testing.assert_allclose(b, b[::-1], rtol=0, atol=1e-9 * abs(b).max())
    assert b[100] < 0 and b[99] > 0 and b[101] > 0   # negative centre, two positive neighbours


def test_printed_h2_zero_lag_is_off_by_five_sixths():
    """The erratum recorded in the module docstring: eq. 13 as printed misses the IDFT at n = 0."""
    N, fs = 256, 500.0
    ref = d.idft_derivative(N, fs, 2)[0]
    printed = d.h2_as_printed(N, fs)[0]
    assert printed - ref == pytest.approx(-(5 / 6) * (2 * np.pi * fs / N) ** 2, rel=1e-9)
    assert d.h2(N, fs)[0] == pytest.approx(ref, rel=1e-12)


def test_impedance_irf_frequency_response():
    """h_s = I h2 + B h1 + K h0 has DFT K + j w B - I w^2 below Nyquist."""
    N, fs, I, B, K = 512, 200.0, 0.18, 1.6, 62.0
    H = np.fft.fft(d.impedance_irf(I, B, K, fs, N))
    w = 2 * np.pi * fs * np.fft.fftfreq(N)
    keep = np.arange(N) != N // 2
    np.testing.assert_allclose(H[keep], (K + 1j * w * B - I * w ** 2)[keep], rtol=1e-9, atol=1e-9)


def test_bad_length():
    with pytest.raises(ValueError, match="even"):
        d.h1(15, 100.0)
