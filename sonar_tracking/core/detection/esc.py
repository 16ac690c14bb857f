"""Extremum seeking control of the detection threshold (ESC paper §3, Figure 1, eqs. 43-46).

The loop drives the scan's mean estimated clutter density ``rho_k`` to the desired density
``rho_D``. Its input is the difference of the inverse densities,

    e_k = 1 / rho_k - 1 / rho_D,                                   (Figure 1, "+" and "-" inputs)

which lies in ``[-1 / rho_D, +inf)`` (``rho_k = 0``, a scan without detections, gives ``+inf``).

Upper branch (magnitude): the compandor of eq. (43),

    f_c(x) = -(1 - exp(-rho_D x)) / rho_D    for x >= 0
    f_c(x) =  (1 - exp(-rho_D x)) / rho_D    for x <  0,

squared and scaled by ``beta = rho_D^2 tau_0`` (eq. 44), which turns inverse-density units into
threshold units: ``beta f_c(e)^2`` runs from ``tau_0`` (far too little clutter) down to 0 at the
optimum, and up to ``(e - 1)^2 tau_0 ~ 2.95 tau_0`` (far too much clutter). Near the optimum it is
``tau_0 (rho_D / rho_k - 1)^2``: small steps where the estimate is noisy, large ones when far off.
Lower branch (direction): the sign block of eq. (46), ``f_s(e) = -sign(e)``: too little clutter
(``e > 0``) lowers the threshold, too much raises it (the density falls monotonically with the
threshold, eq. 16, so the squared error has one extremum).

Integration and dither: the threshold for the next scan is the forward-Euler integral of the
product of the two branches plus the square-wave dither of eq. (45),

    I_{k+1}   = clip(I_k + gain * f_s(e_k) * beta * f_c(e_k)^2, tau_min, tau_max),   I_0 = tau_0
    tau_{k+1} = clip(I_{k+1} + A_max d^(k+1) (-1)^(k+1), tau_min, tau_max),          tau_0 given

with ``A_max = 0.1 tau_0`` and ``d = 0.9``.

Gain: ``beta`` makes every step proportional to ``tau_0``; with a unit integrator gain (the
paper's step) the loop overshoots and cycles on the harbour sonar already from the paper's
``tau_0 = 3``: in Scenario 1 (lambda 1.2) only about a third of the runs are within 5 % of tau*
at scan 30, fewer from higher ``tau_0`` (docs/experiments/2026-11-21-esc-paper-reproduction.md).
The Euler step (the integrator gain) is therefore 0.15 by default: near the optimum the step is
``0.15 tau_0 (rho_D / rho_k - 1)^2``, small against the per-scan noise of ``rho_k`` (about 17 %
with 35 clutter detections), while a scan far from the optimum still moves the threshold by up to
``0.44 tau_0``.

Figure 1 is not in the text, and §3 says both that the
squared compandor output is "multiplied by beta * delta_k" and that the dither is *added* to the
integrated output. We take the second reading: multiplying the integrand by the alternating
dither would flip the direction of every other step whatever the error, and the loop could not
settle. The integrator is clipped to the threshold bounds so it cannot wind up.

Error law (``error``): ``'inverse'`` is the paper's branch above. Its integrand is odd in the
*squared* compandor output, so with a noisy density (few detections per update, as on an imaging
sonar's frames) its zero-mean point lies above ``rho_D``: a mean of ten Poisson detections per
update settles near ``1.1-1.4 rho_D`` (docs/algorithms/active_detector.md). ``'linear'`` keeps the
loop (integrator, dither, bounds, ``beta / rho_D^2 = tau_0`` as the step's unit) and replaces the
two branches by the density error itself,

    step_k = tau_0 * clip(rho_k / rho_D - 1, -1, (e - 1)^2),

whose mean is zero where the mean density is ``rho_D`` whatever its noise; the clip bounds are the
paper branch's own extremes (``-tau_0`` for no clutter, ``(e - 1)^2 tau_0`` for far too much).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ['compandor', 'sign_block', 'ExtremumSeekingController', 'EscState', 'ERROR_LAWS']

ERROR_LAWS = ('inverse', 'linear')
# The paper branch's largest step up, ``(e - 1)^2`` in units of tau_0; the linear law's clip.
_MAX_UP = (math.e - 1.0) ** 2


def compandor(x: float, rho_d: float) -> float:
    """``f_c(x)`` of eq. (43); ``x = +inf`` gives the limit ``-1 / rho_D``."""
    if math.isinf(x) and x > 0:
        return -1.0 / rho_d
    if x >= 0.0:
        return -(1.0 - math.exp(-rho_d * x)) / rho_d
    return (1.0 - math.exp(-rho_d * x)) / rho_d


def sign_block(x: float) -> float:
    """``f_s(x)`` of eq. (46): -1 for x > 0, +1 for x < 0, 0 for x = 0."""
    return -1.0 if x > 0 else (1.0 if x < 0 else 0.0)


@dataclass
class EscState:
    """What the controller knows: scan count, integrator, current threshold, last inputs."""

    k: int = 0
    integrator: float = 0.0
    threshold: float = 0.0
    last_density: float = math.nan
    last_error: float = math.nan


class ExtremumSeekingController:
    """ESC of §3: feed each scan's mean estimated density, get the next scan's threshold."""

    def __init__(self, desired_density: float, tau0: float, tau_min: float, tau_max: float,
                 dither_amplitude: float = 0.1, dither_decay: float = 0.9, gain: float = 0.15,
                 error: str = 'inverse') -> None:
        if error not in ERROR_LAWS:
            raise ValueError(f'ESC error law {error!r} is not one of {list(ERROR_LAWS)}')
        if not desired_density > 0:
            raise ValueError(f'desired clutter density {desired_density} must be > 0')
        if not tau_min <= tau0 <= tau_max:
            raise ValueError(f'tau_0 = {tau0} must lie in [{tau_min}, {tau_max}]')
        self.rho_d = float(desired_density)
        self.tau0 = float(tau0)
        self.tau_min, self.tau_max = float(tau_min), float(tau_max)
        self.a_max = dither_amplitude * tau0
        self.decay = dither_decay
        self.gain = gain
        self.error = error
        self.beta = self.rho_d ** 2 * self.tau0  # eq. (44)
        self.reset()

    def reset(self) -> None:
        """Start again from ``tau_0``."""
        self.state = EscState(k=0, integrator=self.tau0, threshold=self.tau0)

    @property
    def threshold(self) -> float:
        """Threshold to apply to the next scan."""
        return self.state.threshold

    def dither(self, k: int) -> float:
        """``delta_k = A_max d^k (-1)^k`` (eq. 45)."""
        return self.a_max * self.decay ** k * (-1.0 if k % 2 else 1.0)

    def step_size(self, density: float) -> float:
        """The integrand for a scan's mean estimated density: ``f_s(e) beta f_c(e)^2`` (eqs. 43-46), or
        the linear law's ``tau_0 clip(rho_k / rho_D - 1, -1, (e - 1)^2)``."""
        if self.error == 'linear':
            return self.tau0 * min(max(density / self.rho_d - 1.0, -1.0), _MAX_UP)
        e = math.inf if density <= 0 else 1.0 / density - 1.0 / self.rho_d
        return sign_block(e) * self.beta * compandor(e, self.rho_d) ** 2

    def update(self, density: float) -> float:
        """Take the scan's mean estimated density; return the threshold for the next scan."""
        if not (density >= 0 and math.isfinite(density)):
            raise ValueError(f'estimated clutter density {density} must be finite and >= 0')
        s = self.state
        s.last_density = density
        s.last_error = math.inf if density <= 0 else 1.0 / density - 1.0 / self.rho_d
        s.integrator = min(self.tau_max, max(self.tau_min, s.integrator + self.gain * self.step_size(density)))
        s.k += 1
        s.threshold = min(self.tau_max, max(self.tau_min, s.integrator + self.dither(s.k)))
        return s.threshold
