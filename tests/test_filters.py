"""sixplus3/filters.py against scipy.signal, the definitions it follows; and the
log commands' modules without scipy.signal's import (issue 53, item 2)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy import signal

from sixplus3 import filters
from sixplus3.errors import InputError


@pytest.mark.parametrize("order", [1, 2, 3, 4, 5, 8])
@pytest.mark.parametrize(("cutoff", "fs"), [(5.0, 1000.0), (40.0, 1000.0), (124.9, 1000.0),
                                            (3.3, 250.0), (450.0, 1000.0)])
def test_butterworth_and_zero_phase_filter_give_scipys_numbers(order, cutoff, fs):
    ours = filters.butter_sos(order, cutoff, fs)
    ref = signal.butter(order, cutoff, fs=fs, output="sos")
    # the same frequency response (the sections' order and gains may differ)
    w = np.linspace(0.0, np.pi, 257)
    _, h1 = signal.sosfreqz(ours, worN=w)
    _, h2 = signal.sosfreqz(ref, worN=w)
    assert np.max(np.abs(h1 - h2)) < 1e-10
    np.testing.assert_allclose(filters.sosfilt_zi(ref), signal.sosfilt_zi(ref), rtol=1e-12,
                               atol=1e-12)
    rng = np.random.default_rng(order)
    x = np.cumsum(rng.normal(size=(1500, 3)), axis=0) + rng.normal(size=(1500, 3))
    for pad in (0, 1, min(1499, int(3 * fs / cutoff))):
        y1 = filters.sosfiltfilt(ours, x, pad)
        y2 = signal.sosfiltfilt(ref, x, axis=0, padlen=pad)
        assert np.max(np.abs(y1 - y2)) <= 1e-9 * np.max(np.abs(y2))
    # one column alone, as a 1-d array
    y1 = filters.sosfiltfilt(ours, x[:, 0], 30)
    np.testing.assert_allclose(y1, signal.sosfiltfilt(ref, x[:, 0], padlen=30), rtol=0,
                               atol=1e-9 * np.max(np.abs(x)))


def test_single_section_as_a_transfer_function():
    b1, a1 = filters.butter_ba(2, 125.0, 1000.0)
    b2, a2 = signal.butter(2, 125.0, fs=1000.0)
    np.testing.assert_allclose(b1, b2, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(a1, a2, rtol=1e-13, atol=1e-15)
    with pytest.raises(InputError, match="order 1 or 2"):
        filters.butter_ba(4, 125.0, 1000.0)


@pytest.mark.parametrize(("n", "nperseg"), [(3000, 256), (100, 100), (5000, 1024),
                                            (257, 256), (1111, 300),
                                            (20000, 256)])
def test_welch_gives_scipys_density(n, nperseg):
    rng = np.random.default_rng(n)
    x = rng.normal(size=(n, 4)) + np.sin(np.arange(n) * 0.3)[:, None]
    f1, p1 = filters.welch(x, 1000.0, nperseg)
    f2, p2 = signal.welch(x, fs=1000.0, nperseg=nperseg, axis=0)
    np.testing.assert_allclose(f1, f2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p1, p2, rtol=1e-10, atol=1e-14 * np.max(p2))


@pytest.mark.parametrize(("order", "cutoff", "fs"), [(0, 10.0, 1000.0), (4, 0.0, 1000.0),
                                                     (4, 500.0, 1000.0), (4, -1.0, 100.0)])
def test_a_filter_that_cannot_exist_is_refused(order, cutoff, fs):
    with pytest.raises(InputError, match="cut-off"):
        filters.butter_sos(order, cutoff, fs)


def test_padding_longer_than_the_signal_is_refused():
    with pytest.raises(InputError, match="padlen"):
        filters.sosfiltfilt(filters.butter_sos(2, 10.0, 100.0), np.zeros(10), 10)


def test_the_log_commands_do_not_import_scipy_signal():
    """scipy.signal's import alone took 0.8-1.8 s, longer than a short log (issue 53)."""
    code = ("import sys\n"
            "import sixplus3.identification.signals, sixplus3.identification.identify\n"
            "import sixplus3.interaction.observer.wrench, sixplus3.interaction.observer.stream\n"
            "import sixplus3.identification.commission\n"
            "print('scipy.signal' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=300)
    assert out.stdout.strip() == "False", out.stdout + out.stderr
