"""The few digital filters the log commands and the 1 kHz observer use, in numpy and
numba (below the observer, interaction/, and the identification; a bad argument is an
InputError naming the valid range): a Butterworth
low-pass in second-order sections, run forward and backward (zero phase), and Welch's
power spectral density.

Why not ``scipy.signal``: importing it takes 0.8-1.8 s with scipy 1.17 (its
``xp_capabilities`` decorator parses some 650 docstrings at import, scipy PR 24024),
longer than the short logs ``identify check`` and ``wrench`` read (issue 53, item 2).
The functions here follow scipy's definitions step by step, so that they give its
numbers: tests/test_filters.py compares each with ``scipy.signal`` (``butter``,
``sosfilt_zi``, ``sosfiltfilt``, ``welch``) to round-off on random signals.

- :func:`butter_sos`: the analog Butterworth prototype, its poles pre-warped to the
  cut-off and mapped by the bilinear transform; the zeros are all at z = -1.  Each
  second-order section holds one pair of conjugate poles (a first-order section the
  real pole of an odd order) with unit gain at DC, which is the whole filter's gain.
- :func:`sosfiltfilt`: scipy's default padding: an odd extension of ``padlen`` samples
  at both ends, each pass started in the steady state of its first sample
  (``sosfilt_zi``), the sections in transposed direct form II.
- :func:`welch`: a periodic Hann window, half-overlapping segments, each segment's mean
  removed, one-sided density scaling, the mean over the segments.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sixplus3.errors import InputError

#: Welch's segments transformed at once (memory: this many x nperseg x columns).
WELCH_BATCH = 64


def butter_sos(order: int, cutoff: float, fs: float) -> np.ndarray:
    """A digital Butterworth low-pass of ``order`` with its -3 dB point at ``cutoff`` [Hz]
    for the sampling rate ``fs`` [Hz], as second-order sections (n, 6):
    ``[b0, b1, b2, 1, a1, a2]`` per row, like ``scipy.signal.butter(..., output="sos")``."""
    if not (order >= 1 and 0.0 < cutoff < fs / 2.0):
        raise InputError(f"a Butterworth low-pass needs order >= 1 and 0 < cut-off < fs/2 "
                         f"= {fs / 2.0:g} Hz, got order {order}, cut-off {cutoff:g} Hz",
                         value=(order, cutoff), valid=f"order >= 1, cut-off in (0, "
                         f"{fs / 2.0:g}) Hz")
    fs2 = 2.0 * fs
    warped = fs2 * math.tan(math.pi * cutoff / fs)  # the analog cut-off [rad/s]
    rows = []
    for k in range(order // 2):  # the conjugate pairs, from the one nearest the axis
        p = warped * np.exp(1j * math.pi * (2 * k + order + 1) / (2 * order))
        z = (fs2 + p) / (fs2 - p)
        a1, a2 = -2.0 * z.real, abs(z) ** 2
        g = (1.0 + a1 + a2) / 4.0  # unit gain at DC: b(1) = a(1)
        rows.append([g, 2.0 * g, g, 1.0, a1, a2])
    if order % 2:  # the real pole
        z = (fs2 - warped) / (fs2 + warped)
        g = (1.0 - z) / 2.0
        rows.append([g, g, 0.0, 1.0, -z, 0.0])
    return np.array(rows)


def butter_ba(order: int, cutoff: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """The same filter as one transfer function (b, a), for order <= 2 (one section)."""
    if order > 2:
        raise InputError(f"butter_ba gives one section: order 1 or 2, got {order}",
                         value=order, valid="1 or 2")
    sos = butter_sos(order, cutoff, fs)[0]
    n = order + 1
    return sos[:n].copy(), sos[3:3 + n].copy()


def sosfilt_zi(sos: np.ndarray) -> np.ndarray:
    """The sections' initial states (n, 2) for a unit step's steady state
    (``scipy.signal.sosfilt_zi``): each section's state for a constant input of the DC
    gain of the sections before it."""
    zi = np.zeros((len(sos), 2))
    scale = 1.0
    for s, (b0, b1, b2, _a0, a1, a2) in enumerate(sos):
        # transposed direct form II at rest, input 1 and output dc: z2 = b2 - a2 dc and
        # z1 = b1 - a1 dc + z2 (scipy's lfilter_zi solves the same two equations)
        dc = (b0 + b1 + b2) / (1.0 + a1 + a2)
        z2 = b2 - a2 * dc
        z1 = b1 - a1 * dc + z2
        zi[s] = scale * np.array([z1, z2])
        scale *= dc
    return zi


@njit(cache=True, error_model="numpy")
def _sosfilt(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> np.ndarray:
    """The sections in transposed direct form II along axis 0 of x (n, m), each
    column's state starting at zi (sections, 2, m); returns the output (n, m)."""
    n, m = x.shape
    y = x.copy()
    for s in range(sos.shape[0]):
        b0, b1, b2 = sos[s, 0], sos[s, 1], sos[s, 2]
        a1, a2 = sos[s, 4], sos[s, 5]
        for j in range(m):
            z1, z2 = zi[s, 0, j], zi[s, 1, j]
            for i in range(n):
                u = y[i, j]
                out = b0 * u + z1
                z1 = b1 * u - a1 * out + z2
                z2 = b2 * u - a2 * out
                y[i, j] = out
    return y


def sosfiltfilt(sos: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """Zero-phase filtering of x along axis 0 (``scipy.signal.sosfiltfilt`` with
    ``axis=0`` and its default odd padding of ``padlen`` samples)."""
    x = np.asarray(x, dtype=float)
    flat = x.ndim == 1
    x2 = x.reshape(len(x), -1)
    n = len(x2)
    if not 0 <= padlen < n:
        raise InputError(f"padlen must be in [0, {n - 1}] for {n} samples, got {padlen}",
                         value=padlen, valid=f"[0, {n - 1}]")
    if padlen:
        head = 2.0 * x2[0] - x2[padlen:0:-1]
        tail = 2.0 * x2[-1] - x2[-2:-padlen - 2:-1]
        ext = np.concatenate([head, x2, tail])
    else:
        ext = x2
    sos = np.ascontiguousarray(sos, dtype=float)
    zi = sosfilt_zi(sos)[:, :, None]
    y = _sosfilt(sos, np.ascontiguousarray(ext), zi * ext[0][None, None, :])
    y = _sosfilt(sos, np.ascontiguousarray(y[::-1]), zi * y[-1][None, None, :])[::-1]
    if padlen:
        y = y[padlen:-padlen]
    y = np.ascontiguousarray(y)
    return y.reshape(n) if flat else y.reshape(x.shape)


def welch(x: np.ndarray, fs: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """Welch's power spectral density of x along axis 0 (``scipy.signal.welch`` with
    ``axis=0`` and its defaults): the frequencies (k,) and the density (k, m)."""
    x = np.asarray(x, dtype=float)
    x2 = x.reshape(len(x), -1)
    n = len(x2)
    nperseg = int(min(nperseg, n))
    step = nperseg - nperseg // 2
    win = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(nperseg) / nperseg)  # periodic Hann
    scale = 1.0 / (fs * float(np.sum(win ** 2)))
    starts = np.arange(0, n - nperseg + 1, step)
    total = np.zeros((nperseg // 2 + 1, x2.shape[1]))
    for i in range(0, len(starts), WELCH_BATCH):  # the segments a batch at a time: the
        # memory stays at WELCH_BATCH segments however long the log
        idx = starts[i:i + WELCH_BATCH, None] + np.arange(nperseg)[None, :]
        seg = x2[idx]  # (segments, nperseg, m)
        seg = seg - seg.mean(axis=1, keepdims=True)
        spec = np.fft.rfft(seg * win[None, :, None], axis=1)
        total += (spec.real ** 2 + spec.imag ** 2).sum(axis=0)
    dens = total * (scale / len(starts))
    dens[1:] *= 2.0
    if nperseg % 2 == 0:
        dens[-1] /= 2.0
    f = np.fft.rfftfreq(nperseg, 1.0 / fs)
    return f, dens.reshape((len(f),) + x.shape[1:])


__all__ = ["butter_ba", "butter_sos", "sosfilt_zi", "sosfiltfilt", "welch"]
