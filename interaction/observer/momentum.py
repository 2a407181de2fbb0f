"""The momentum observer, once (De Luca and Mattone 2003; docs/interaction.md): the
batch estimator (:func:`~sixplus3.interaction.observer.wrench.estimate`), the stream
(:class:`~sixplus3.interaction.observer.stream.WrenchStream`, which lead-through reads) and the
contact guard (:class:`~sixplus3.interaction.contact.guard.ContactGuard`) all run
:func:`~sixplus3.interaction.observer._tick_kernel.observe`, through :class:`MomentumObserver`
or :func:`momentum_observer`.  What differs between them is only what they feed it:
the rates (a zero-lag filter offline, a causal one in the stream, the encoder's
difference in the guard), the model's M and h (Pinocchio or the compiled model at the
measured state, or the guard's tables along its path) and the torque held over a tick.

The residual r follows tau_ext = M theta_ddot + h - tau (a first-order low-pass of gain
K): r = K (p - p0 - integral of (tau - h + M_dot theta_dot + r)), p = M theta_dot the
generalized momentum.  ``lag``: the ticks by which the momentum's rate lags the sample
(an encoder's difference is the rate half a tick ago: lag 1/2 compares it with the
integral up to then, with no K dt/2 M theta_ddot lag)."""

from __future__ import annotations

import numpy as np

from sixplus3.errors import check_number
from sixplus3.interaction.observer._tick_kernel import observe, observe_series


def _state() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return (np.zeros((9, 9)), np.zeros(9), np.zeros(9), np.zeros(9),
            np.zeros(1, dtype=np.int64))


class MomentumObserver:
    """The observer's state (M at the last sample, the first momentum, the integral,
    the residual, whether a sample was seen) and its settings (``gain`` [1/s],
    ``lag`` [ticks]).  :meth:`step` takes one sample and returns the residual r (the
    observer's own array: copy it to keep it)."""

    def __init__(self, gain: float, lag: float = 0.0) -> None:
        self.gain = check_number("observer gain [1/s]", gain, 1e-9, 1e6)
        self.lag = check_number("observer lag [ticks]", lag, 0.0, 1.0)
        #: (M_prev, p0, integral, r, started): the kernel's state, in place
        self.state = _state()

    def reset(self) -> None:
        """Forget the past: the next sample is the first (r = 0 there)."""
        for a in self.state:
            a[...] = 0

    @property
    def r(self) -> np.ndarray:
        """The residual [N m] (9), an estimate of tau_ext."""
        return self.state[3]

    @property
    def started(self) -> bool:
        return bool(self.state[4][0])

    def step(self, tau: np.ndarray, theta_dot: np.ndarray, M: np.ndarray, h: np.ndarray,
             dt: float) -> np.ndarray:
        """One sample: the torque held over the tick that ends here ``tau``, the rates,
        M (9, 9) and h (9) there, the tick ``dt`` [s]; the residual."""
        observe(tau, theta_dot, M, h, dt, self.gain, self.lag, self.state)
        return self.state[3]


def momentum_observer(t: np.ndarray, tau: np.ndarray, theta_dot: np.ndarray,
                      M: np.ndarray, h: np.ndarray, gain: float, lag: float = 0.0
                      ) -> np.ndarray:
    """(n, 9) the residuals of a log (t (n,) [s], tau, theta_dot, h (n, 9), M (n, 9, 9))
    from its first sample: :class:`MomentumObserver` over every sample, in one compiled
    loop."""
    obs = MomentumObserver(gain, lag)
    out = np.empty((len(t), 9))
    observe_series(np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(tau, float),
                   np.ascontiguousarray(theta_dot, float), np.ascontiguousarray(M, float),
                   np.ascontiguousarray(h, float), obs.gain, obs.lag, obs.state, out)
    return out


__all__ = ["MomentumObserver", "momentum_observer"]
