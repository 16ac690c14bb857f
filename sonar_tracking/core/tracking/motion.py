"""Motion models: state transition matrices of ESC paper eqs. (3)-(4).

The state is ordered as eq. (1), positions then velocities, ``[p_1 .. p_d, v_1 .. v_d]``:
``[x, y, vx, vy]`` in the plane. Frames follow REP-103 (x forward, y left, angles
counter-clockwise), so a counter-clockwise turn has a positive turn rate.

On the sign of the turn rate. The paper says that in eq. (4) a positive Omega is a clockwise
turn. In a right-handed x-y frame, eq. (4) with ``Omega > 0`` rotates the velocity by
``+Omega * Delta``, which is counter-clockwise (x towards y). Our modes therefore are
``cv`` (eq. 3), ``ccw`` (eq. 4 with ``+Omega``) and ``cw`` (eq. 4 with ``-Omega``), matching
``TRACK_DTYPE``'s ``mode_cv, mode_ccw, mode_cw`` and the simulator's Table 2 trajectories.

Models are shared: any tracker of the package (IMM-IPDA, GPF) takes its transition matrices
from here. :class:`ConstantVelocity` works in any number of spatial dimensions;
:class:`ConstantTurn` is planar.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.tracking.errors import TrackingInputError

__all__ = ['MotionModel', 'ConstantVelocity', 'ConstantTurn', 'position_matrix']


class MotionModel:
    """Interface of a linear motion model: ``transition(dt)`` is the matrix F of eq. (2)."""

    #: Short name, used as the IMM mode name (``cv``, ``ccw``, ``cw``).
    name: str = ''
    #: Spatial dimension d; the state has 2 d components.
    ndim: int = 2

    @property
    def state_dim(self) -> int:
        """Length of the state vector, ``2 * ndim``."""
        return 2 * self.ndim

    def transition(self, dt: float) -> np.ndarray:
        """State transition matrix ``F`` over ``dt`` seconds, shape ``(2 d, 2 d)``."""
        raise NotImplementedError


@dataclass(frozen=True)
class ConstantVelocity(MotionModel):
    """Constant velocity, eq. (3): ``F = [[I, dt I], [0, I]]`` in ``ndim`` spatial dimensions."""

    ndim: int = 2
    name: str = 'cv'

    def __post_init__(self) -> None:
        if not isinstance(self.ndim, int) or self.ndim < 1:
            raise TrackingInputError(f'ConstantVelocity.ndim = {self.ndim!r} must be an integer >= 1')

    def transition(self, dt: float) -> np.ndarray:
        d = self.ndim
        f = np.eye(2 * d)
        f[:d, d:] = dt * np.eye(d)
        return f


@dataclass(frozen=True)
class ConstantTurn(MotionModel):
    """Constant turn rate with known rate, eq. (4), in the plane.

    ``turn_rate`` [rad/s] is positive for a counter-clockwise turn (REP-103), see the module
    docstring. As ``turn_rate * dt -> 0`` the matrix tends to eq. (3); below 1e-9 rad it is
    evaluated by its series so that a zero rate gives constant velocity exactly.
    """

    turn_rate: float
    name: str = 'ctr'

    def __post_init__(self) -> None:
        if not math.isfinite(self.turn_rate):
            raise TrackingInputError(f'ConstantTurn.turn_rate = {self.turn_rate!r} must be finite')

    @property
    def ndim(self) -> int:  # type: ignore[override]
        return 2

    def transition(self, dt: float) -> np.ndarray:
        w = self.turn_rate
        a = w * dt
        s, c = math.sin(a), math.cos(a)
        if abs(a) < 1e-9:
            # sin(a)/w -> dt, (1 - cos a)/w -> w dt^2 / 2
            sw, cw = dt, 0.5 * w * dt * dt
        else:
            sw, cw = s / w, (1.0 - c) / w
        return np.array([[1.0, 0.0, sw, -cw],
                         [0.0, 1.0, cw, sw],
                         [0.0, 0.0, c, -s],
                         [0.0, 0.0, s, c]])


def position_matrix(ndim: int = 2) -> np.ndarray:
    """Measurement matrix ``H = [I_d 0_d]`` of eq. (27): the position part of the state."""
    h = np.zeros((ndim, 2 * ndim))
    h[:, :ndim] = np.eye(ndim)
    return h
