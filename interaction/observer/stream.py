"""The momentum observer one sample at a time, for a 1 kHz controller
(docs/interaction.md, "Streaming"): :class:`WrenchStream`, on Pinocchio's state
(:class:`~sixplus3.interaction.observer.wrench.SingleState`) or the CasADi model compiled to C
(:class:`~sixplus3.interaction.observer.compiled_state.CompiledState`), whose sample is then one
compiled call (:func:`~sixplus3.interaction.observer._tick_kernel.stream_tick`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from sixplus3.errors import InputError, check_number
from sixplus3.filters import butter_ba
from sixplus3.interaction.observer._tick_kernel import momentum, stream_tick, velocity
from sixplus3.interaction.observer.momentum import MomentumObserver
from sixplus3.interaction.observer.wrench import (
    GAIN,
    MIN_RATE,
    MODEL_SIGMA,
    N_SIGMA,
    V_BAND,
    SingleState,
    torque_sigma,
)
from sixplus3.robot_description.robot import Robot, require_robot

if TYPE_CHECKING:
    from sixplus3.interaction.observer.compiled_state import CompiledState


class WrenchStream:
    """The momentum observer fed one sample at a time, for a 1 kHz controller:
    ``update(theta, tau)`` -> (wrench (6,), std (6,), band (6,), contact).

    Small matrices on a multi-threaded BLAS cost more in thread hand-offs than in work
    (measured: 7.7 ms a sample with another process busy, 0.9 ms on one thread), so the
    stream limits this process's BLAS to one thread when it is built, as a real-time
    loop would (``threadpoolctl``).

    The velocity is causal here: the encoder's difference through a second-order
    Butterworth low-pass at rate / 8 (its group delay, about 0.3 ms at 1 kHz, is the
    price of running online; the offline :func:`estimate` filters without lag).  The
    drive's torque is taken as held over the previous tick.  ``compiled``: the state
    (forward kinematics, J, M, h) from the CasADi model compiled to C
    (:class:`~sixplus3.interaction.observer.compiled_state.CompiledState`, the same numbers to
    1e-10) instead of Pinocchio.  Cost per sample: BENCHMARKS.md, "Sensorless touch" and
    "Lead-through"."""

    def __init__(self, robot: Robot, rate: float, gain: float = GAIN,
                 monitor_noise: float = 0.005, model_sigma: float = MODEL_SIGMA,
                 v_band: float = V_BAND, n_sigma: float = N_SIGMA,
                 compiled: bool = False) -> None:
        # deferred: threadpoolctl loads only when this runs
        from threadpoolctl import threadpool_limits

        self.robot = require_robot(robot)
        self._blas = threadpool_limits(limits=1, user_api="blas")  # held with the stream
        if not (isinstance(rate, (int, float)) and math.isfinite(rate)
                and MIN_RATE <= rate <= 20000.0):
            raise InputError(f"rate must be in [{MIN_RATE:g}, 20000] Hz, got {rate!r}",
                             value=rate, valid=f"[{MIN_RATE:g}, 20000] Hz")
        if not (isinstance(gain, (int, float)) and math.isfinite(gain)
                and 1.0 <= gain <= min(2000.0, 2 * math.pi * rate / 4)):
            raise InputError(f"gain must be in [1, {min(2000.0, 2 * math.pi * rate / 4):g}]"
                             f"/s, got {gain!r}", value=gain, valid="a positive gain")
        self.dt, self.gain = 1.0 / rate, float(gain)
        # the observer's settings, by name with their range (a NaN or a negative noise
        # would make every threshold meaningless, silently)
        monitor_noise = check_number("monitor_noise [N m]", monitor_noise, 0.0, 1.0)
        model_sigma = check_number("model_sigma [N m]", model_sigma, 0.0, 10.0)
        v_band = check_number("v_band [rad/s]", v_band, 0.0, 100.0)
        n_sigma = check_number("n_sigma", n_sigma, 0.0, 100.0)
        if compiled:  # the CasADi model compiled to C (interaction/observer/compiled_state.py)
            from sixplus3.interaction.observer.compiled_state import (
                CompiledState,  # deferred: its first build compiles C (seconds, once)
            )

            self._compiled: CompiledState | None = CompiledState(self.robot)
            self.model: SingleState | CompiledState = self._compiled
            # one compiled call per sample where the model's C is on disk
            # (_native_update)
            self._native = self._compiled.native_args()
        else:
            self.model = SingleState(self.robot)
            self._compiled, self._native = None, None
        b, a = butter_ba(2, rate / 8.0, rate)
        #: the velocity's biquad: (b, a, its state z (2, 9), transposed direct form II)
        self._biquad = (np.asarray(b, dtype=float), np.asarray(a, dtype=float),
                        np.zeros((2, 9)))
        self.rate = float(rate)
        # the observer's state, on preallocated arrays (interaction/observer/_tick_kernel.py)
        self._prev_theta = np.zeros(9)
        self._have_theta = False
        self._prev_tau = np.zeros(9)
        self.observer = MomentumObserver(self.gain)  # the one observer (momentum.py)
        sig = torque_sigma(self.robot, monitor_noise)
        var = np.full(9, sig ** 2 * self.gain * self.dt / 2.0 + model_sigma ** 2)
        #: the wrench's uncertainty: (the residual's variance, the Coulomb friction per
        #: joint, the speed below which a joint's friction is a band)
        self._settings = (var, self.robot.motors.coulomb_per_joint, float(v_band))
        self.v_band, self.n_sigma = v_band, n_sigma
        self._thd = np.zeros(9)
        self._out = (np.zeros(6), np.zeros(6), np.zeros(6))
        if self._native is not None:  # numba loads the kernel now, not at a sample: a
            # reading not finite returns at once and changes nothing
            self._tick(np.full(9, np.nan), np.zeros(9), self._native)

    def reset(self) -> None:
        """Start again: the filter, the observer and the pose tracking forget the past
        (the next sample is the first)."""
        self._biquad[2][:] = 0.0
        self._have_theta = False
        self.observer.reset()
        self.model.reset()

    def update(self, theta: np.ndarray, tau: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        theta = np.asarray(theta, dtype=float).reshape(9)
        tau = np.asarray(tau, dtype=float).reshape(9)
        if (self._native is not None and self._have_theta
                and self._compiled is not None and self._compiled._have):
            return self._native_update(theta, tau, self._native, self._compiled)
        if not (np.isfinite(theta).all() and np.isfinite(tau).all()):
            raise InputError("theta and tau must be 9 finite numbers each", value=None,
                             valid="finite")
        thd = np.empty(9)
        b, a, z = self._biquad
        velocity(theta, self._prev_theta, self._have_theta, self.rate, b, a, z, thd)
        J, M, h, _ = self.model.state(theta, thd)
        #: this sample's (J, M, h, theta_dot), for a controller built on the stream
        #: (lead-through)
        self.sample = (J, M, h, thd)
        w, std, band = np.empty(6), np.empty(6), np.empty(6)
        momentum(tau, thd, J, M, h, self._prev_tau, self.observer.state, self.gain,
                 self.dt, self._settings, (w, std, band))
        self._prev_theta[:] = theta
        self._have_theta = True
        return w, std, band, bool((np.abs(w) > self.n_sigma * std + band).any())

    def _tick(self, theta: np.ndarray, tau: np.ndarray, args: tuple[object, ...]) -> int:
        """_tick_kernel.stream_tick on this stream's state: its code."""
        filt = (self._prev_theta, self.rate, *self._biquad, self._thd)
        obs = (self._prev_tau, self.observer.state, self.gain, self.dt, self._settings)
        return int(stream_tick(theta, tau, filt, args, obs, self.n_sigma, self._out))

    def _native_update(self, theta: np.ndarray, tau: np.ndarray, args: tuple[object, ...],
                       model: CompiledState
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """:meth:`update` in one compiled call (_tick_kernel.stream_tick: the generated
        C called from the kernel); ``sample`` is then the model's arrays, valid
        until the next sample."""
        w, std, band = self._out
        code = self._tick(theta, tau, args)
        if code == -1:
            raise InputError("theta and tau must be 9 finite numbers each", value=None,
                             valid="finite")
        if code == -2:
            model.reset()  # start again from the full forward kinematics next time
            raise InputError("forward kinematics did not converge for these angles",
                             value=None, valid="angles of an assembly")
        model.native_done()
        J, M, h, _ = model._out
        self.sample = (J, M, h, self._thd)
        return w.copy(), std.copy(), band.copy(), code == 1


__all__ = ["WrenchStream"]
