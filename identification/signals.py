"""Velocities and accelerations from logged positions: a zero-phase low-pass filter, then
central differences (docs/identification.md, "The filter").

- The positions are filtered by a Butterworth low-pass of order 4 run forward and
  backward (``sosfiltfilt``: zero phase, order 8 in effect; sixplus3/filters.py
  gives scipy.signal's numbers without its import time), then
  differentiated twice by central differences (``numpy.gradient``).
- The drive holds each torque over its tick (from t_k to t_k+1), while the encoder is
  read at t_k: the torque at t_k is the mean of the two held values around it,
  (tau_k-1 + tau_k) / 2 (``held=True``, the default; the drives of the feed and of the
  virtual prototype).  A log whose torque monitor samples the torque at t_k takes
  ``held=False``.
- The logged torques go through the same filter ("parallel filtering", Gautier 1997),
  so that torques and states keep the same attenuation and no phase lag.
- The cut-off: by default :data:`CUTOFF_FACTOR` times the bandwidth of the motion (the
  frequency below which 99 % of the joint accelerations' power lies: the torques follow
  the accelerations; the encoder's quantisation noise, white up to the Nyquist
  frequency, holds far less than 1 % of it at 20 bit), within
  [:data:`MIN_CUTOFF`, rate / :data:`RATE_PER_CUTOFF`].  A log whose rate is below
  ``RATE_PER_CUTOFF`` times the cut-off is refused.
- The Coulomb friction switches at a reversal within a tick: its regressor column,
  tanh(theta_dot / omega_c), is computed from a velocity filtered only at rate / 8 and
  then filtered like the torques (``coulomb_velocity``).
- Then the samples are decimated to about :data:`SAMPLES_PER_CUTOFF` per cut-off period
  (the filtered signals carry nothing above the cut-off), and :data:`EDGE` cut-off
  periods at both ends are dropped (the filter's start-up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sixplus3.control.file.drive_log import DriveLog
from sixplus3.errors import InputError, check_number
from sixplus3.filters import butter_sos, sosfiltfilt, welch

ORDER = 4
CUTOFF_FACTOR = 2.5
MIN_CUTOFF = 5.0
RATE_PER_CUTOFF = 8.0
SAMPLES_PER_CUTOFF = 5.0
EDGE = 2.0
#: The lowest cut-off a user may set [Hz]: below it the filter's edges (EDGE / fc s at
#: each end) eat any log, and the filter's design is numerically singular (1e-9 Hz).
LOWEST_CUTOFF = 1.0


@dataclass
class Filtered:
    """The log's states and torques after the filter, decimated: t (n,), theta,
    theta_dot, theta_ddot, tau (n, 9); the cut-off [Hz] and the decimation step."""

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    tau: np.ndarray
    cutoff_hz: float
    step: int
    #: the filtered Coulomb law tanh(theta_dot / omega_c) (n, 9) (module doc), or None
    coulomb: np.ndarray | None = None


def bandwidth(log: DriveLog) -> float:
    """The frequency [Hz] below which 99 % of the power of the joint accelerations lies
    (Welch's estimate on the second differences of the positions)."""
    rate = log.rate
    vel = np.diff(log.theta, n=2, axis=0) * rate ** 2
    vel = vel - vel.mean(axis=0)
    nper = int(min(len(vel), max(256, 2 ** int(math.log2(max(rate, 2.0))))))
    f, p = welch(vel, rate, nper)
    total = p.sum(axis=1)
    # the encoder's quantisation noise is white: its floor (the median level of the upper
    # half of the band) is taken out before the 99 % point is found, so a log with long
    # holds (little motion, the same noise) does not read as a wide band
    floor = float(np.median(total[f > rate / 4.0])) if np.any(f > rate / 4.0) else 0.0
    total = np.maximum(total - floor, 0.0)
    c = np.cumsum(total)
    if c[-1] <= 0:
        return MIN_CUTOFF
    return float(f[min(int(np.searchsorted(c, 0.99 * c[-1])), len(f) - 1)])


def choose_cutoff(log: DriveLog, cutoff: float | None = None) -> float:
    """The cut-off [Hz]: ``cutoff`` if given, else the default of the module doc; an
    InputError when the log's rate cannot carry it."""
    rate = log.rate
    if cutoff is None:
        cutoff = min(max(CUTOFF_FACTOR * bandwidth(log), MIN_CUTOFF), rate / RATE_PER_CUTOFF)
    cutoff = check_number("the cut-off [Hz]", cutoff, LOWEST_CUTOFF, math.inf)
    if rate < RATE_PER_CUTOFF * cutoff or rate < RATE_PER_CUTOFF * MIN_CUTOFF:
        need = RATE_PER_CUTOFF * max(cutoff, MIN_CUTOFF)
        raise InputError(f"{log.name}: its rate {rate:.6g} Hz is below what the filter "
                         f"needs ({RATE_PER_CUTOFF:g} x the {max(cutoff, MIN_CUTOFF):g} Hz "
                         f"cut-off = {need:g} Hz)", value=rate, valid=f">= {need:g} Hz")
    return float(cutoff)


def filter_log(log: DriveLog, cutoff: float | None = None, decimate: bool = True,
               held: bool = True, coulomb_velocity: float | None = None) -> Filtered:
    """The log filtered and differentiated (module doc)."""
    fc = choose_cutoff(log, cutoff)
    rate = log.rate
    dt = 1.0 / rate
    sos = butter_sos(ORDER, fc, rate)
    pad = min(len(log.t) - 1, int(3 * rate / fc))
    th = sosfiltfilt(sos, log.theta, pad)
    tau_k = log.tau
    if held:
        tau_k = np.vstack([tau_k[:1], 0.5 * (tau_k[1:] + tau_k[:-1])])
    tau = sosfiltfilt(sos, tau_k, pad)
    thd = np.gradient(th, dt, axis=0)
    thdd = np.gradient(thd, dt, axis=0)
    coul = None
    if coulomb_velocity is not None:
        # the dry friction switches within a tick at a reversal, far faster than the
        # cut-off: its law is evaluated on a velocity filtered only at rate / 8 and
        # then put through the same filter as the torques (parallel filtering of a
        # column that is linear in its parameter), so both see the same smeared switch
        light = butter_sos(ORDER, rate / RATE_PER_CUTOFF, rate)
        v_fast = np.gradient(sosfiltfilt(light, log.theta, pad), dt, axis=0)
        coul = sosfiltfilt(sos, np.tanh(v_fast / coulomb_velocity), pad)
    step = max(1, int(rate / (SAMPLES_PER_CUTOFF * fc))) if decimate else 1
    edge = int(math.ceil(EDGE * rate / fc))
    keep = np.arange(edge, len(log.t) - edge, step)
    if len(keep) < 20:
        raise InputError(f"{log.name}: {log.duration:.3g} s is too short for the filter "
                         f"(cut-off {fc:g} Hz)", value=log.duration,
                         valid=f">= {(2 * edge + 20 * step) / rate:.3g} s")
    return Filtered(t=log.t[keep], theta=th[keep], theta_dot=thd[keep],
                    theta_ddot=thdd[keep], tau=tau[keep], cutoff_hz=fc, step=step,
                    coulomb=None if coul is None else coul[keep])


__all__ = ["Filtered", "bandwidth", "choose_cutoff", "filter_log"]
