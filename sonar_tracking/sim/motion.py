"""Target and platform motion for the simulator.

Every trajectory gives the state ``[x, y, vx, vy]`` and a body heading at any time ``t >= 0`` [s]
in the world frame (REP-103: x forward, y left, angles counter-clockwise).

* :class:`ScriptedTrajectory`: constant velocity and constant-turn-rate segments, in closed
  form. A positive turn rate turns counter-clockwise (the CCW segments of ESC paper Table 2); the
  paper's eq. (4) matrix with ``Omega > 0`` rotates the velocity the same way in a right-handed
  x-y frame, so our CCW model is eq. (4) with ``+Omega`` and CW is ``-Omega``.
* :class:`DraggedTrajectory`: the FLS paper's targets "dragged by ropes and current": a nominal
  straight tow plus a smooth random deviation (a sum of random sinusoids in a band of periods),
  and a heading that wobbles around the tow direction so the target's aspect keeps changing.
  The deviation is bounded and has an analytic velocity, and the whole path is fixed by the
  generator at construction, so it can be sampled at any time.
* :class:`WaypointTrajectory`: straight legs at constant speed round a closed polygon (a diver's
  patrol, a platform's survey lines).
* :class:`RelativeTrajectory`: a path given in the frame of a moving platform (a target that
  keeps station ahead of an AUV).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ['Trajectory', 'StaticTrajectory', 'Segment', 'ScriptedTrajectory', 'DraggedTrajectory', 'BandLimitedNoise',
           'WaypointTrajectory', 'RelativeTrajectory']


class Trajectory:
    """Interface: ``state(t) -> [x, y, vx, vy]`` and ``heading(t)`` [rad]."""

    def state(self, t: float) -> np.ndarray:
        raise NotImplementedError

    def heading(self, t: float) -> float:
        """Body heading; by default the direction of motion (kept when the target stops)."""
        s = self.state(t)
        if math.hypot(s[2], s[3]) < 1e-9:
            return 0.0
        return math.atan2(s[3], s[2])


@dataclass(frozen=True)
class StaticTrajectory(Trajectory):
    """A target or platform that does not move."""

    x: float
    y: float
    yaw: float = 0.0

    def state(self, t: float) -> np.ndarray:
        return np.array([self.x, self.y, 0.0, 0.0])

    def heading(self, t: float) -> float:
        return self.yaw


@dataclass(frozen=True)
class Segment:
    """``duration`` seconds at ``turn_rate`` [rad/s] (0 = constant velocity, > 0 = CCW)."""

    duration: float
    turn_rate: float = 0.0


@dataclass(frozen=True)
class ScriptedTrajectory(Trajectory):
    """Piecewise CV / CTR motion from ``(x0, y0)`` with initial velocity ``(vx0, vy0)``.

    After the last segment the target keeps a constant velocity.
    """

    x0: float
    y0: float
    vx0: float
    vy0: float
    segments: tuple[Segment, ...] = ()
    _knots: list = field(default_factory=list, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # State at the start of every segment, and at the end of the last one.
        t, s = 0.0, np.array([self.x0, self.y0, self.vx0, self.vy0], dtype=float)
        knots = [(0.0, s)]
        for seg in self.segments:
            if seg.duration <= 0:
                raise ValueError(f'segment duration {seg.duration} must be > 0')
            s = _propagate(s, seg.turn_rate, seg.duration)
            t += seg.duration
            knots.append((t, s))
        object.__setattr__(self, '_knots', knots)

    def state(self, t: float) -> np.ndarray:
        t = max(0.0, float(t))
        elapsed = 0.0
        for i, seg in enumerate(self.segments):
            if t <= elapsed + seg.duration:
                return _propagate(self._knots[i][1], seg.turn_rate, t - elapsed)
            elapsed += seg.duration
        t_last, s_last = self._knots[-1]
        return _propagate(s_last, 0.0, t - t_last)


def _propagate(s: np.ndarray, omega: float, dt: float) -> np.ndarray:
    """Exact CV (``omega = 0``) or CTR motion over ``dt`` (the flow of ESC eqs. 3-4)."""
    x, y, vx, vy = s
    if abs(omega) < 1e-12:
        return np.array([x + vx * dt, y + vy * dt, vx, vy])
    sw, cw = math.sin(omega * dt), math.cos(omega * dt)
    return np.array([x + (sw * vx - (1 - cw) * vy) / omega, y + ((1 - cw) * vx + sw * vy) / omega,
                     cw * vx - sw * vy, sw * vx + cw * vy])


class BandLimitedNoise:
    """A smooth zero-mean random signal: a sum of sinusoids with periods in ``[p_min, p_max]``.

    ``value(t)`` has standard deviation ``std`` per component; ``rate(t)`` is its exact derivative.
    """

    def __init__(self, rng: np.random.Generator, std: float, p_min: float, p_max: float,
                 dims: int = 2, n_terms: int = 8) -> None:
        if p_min <= 0 or p_max < p_min:
            raise ValueError('need 0 < p_min <= p_max')
        self.omega = 2 * math.pi / rng.uniform(p_min, p_max, size=(dims, n_terms))
        self.phase = rng.uniform(0.0, 2 * math.pi, size=(dims, n_terms))
        # Equal power per term; a sinusoid of amplitude a has variance a^2 / 2.
        self.amp = np.full((dims, n_terms), std * math.sqrt(2.0 / n_terms))

    def value(self, t: float) -> np.ndarray:
        return np.sum(self.amp * np.sin(self.omega * t + self.phase), axis=1)

    def rate(self, t: float) -> np.ndarray:
        return np.sum(self.amp * self.omega * np.cos(self.omega * t + self.phase), axis=1)


class DraggedTrajectory(Trajectory):
    """A towed target: ``start + velocity * t`` plus a smooth random deviation, wobbling heading.

    Parameters
    ----------
    start, velocity : nominal tow start [m] and velocity [m/s].
    rng : the generator that fixes the random deviation and heading wobble.
    deviation_std : std of the position deviation from the tow line [m].
    periods : band of periods of the deviation [s]; short periods give sudden changes.
    yaw_std : std of the heading wobble around the tow direction [rad].
    """

    def __init__(self, start: tuple[float, float], velocity: tuple[float, float], rng: np.random.Generator,
                 deviation_std: float = 0.3, periods: tuple[float, float] = (4.0, 30.0),
                 yaw_std: float = math.radians(25.0), yaw_offset: float = 0.0) -> None:
        self.start = np.asarray(start, dtype=float)
        self.velocity = np.asarray(velocity, dtype=float)
        self.deviation = BandLimitedNoise(rng, deviation_std, *periods, dims=2)
        self.yaw = BandLimitedNoise(rng, yaw_std, periods[0] * 2, periods[1] * 2, dims=1)
        speed = float(np.hypot(*self.velocity))
        self.base_heading = (math.atan2(self.velocity[1], self.velocity[0]) if speed > 0 else 0.0) + yaw_offset

    def state(self, t: float) -> np.ndarray:
        t = max(0.0, float(t))
        p = self.start + self.velocity * t + self.deviation.value(t)
        v = self.velocity + self.deviation.rate(t)
        return np.array([p[0], p[1], v[0], v[1]])

    def heading(self, t: float) -> float:
        return self.base_heading + float(self.yaw.value(max(0.0, float(t)))[0])


class WaypointTrajectory(Trajectory):
    """Legs at constant speed through ``points``, from the last back to the first, round and round.

    ``speeds`` [m/s] has one value per leg (leg k from point k to point k + 1). With ``turn_radius``
    0 the velocity changes at once at a waypoint; with ``turn_radius`` rho > 0 each corner is cut by
    the circular arc of radius rho tangent to both legs (shrunk where the legs are too short for it:
    the arc never takes more than half of either leg), flown at the next leg's speed, so the
    heading turns at ``speed / rho``. The heading is the direction of motion.
    """

    def __init__(self, points, speeds, turn_radius: float = 0.0) -> None:
        self.points = np.asarray(points, dtype=float)
        legs = np.roll(self.points, -1, axis=0) - self.points
        lengths = np.hypot(legs[:, 0], legs[:, 1])
        speeds = np.broadcast_to(np.asarray(speeds, dtype=float), lengths.shape)
        if np.any(lengths <= 0) or np.any(speeds <= 0) or not turn_radius >= 0:
            raise ValueError('waypoints must differ, speeds be > 0 and the turn radius >= 0')
        n = len(lengths)
        u = legs / lengths[:, None]
        # Corner k (at point k) joins leg k-1 to leg k: the arc starts `cut` before the point on leg
        # k-1 and ends `cut` after it on leg k.
        cut, radius, turn = np.zeros(n), np.zeros(n), np.zeros(n)
        for k in range(n):
            a, b = u[k - 1], u[k]
            angle = math.atan2(a[0] * b[1] - a[1] * b[0], float(a @ b))     # signed turn
            if turn_radius > 0 and abs(angle) > 1e-9:
                t = math.tan(abs(angle) / 2)
                room = 0.5 * min(lengths[k - 1], lengths[k])
                radius[k] = min(turn_radius, room / t)
                cut[k], turn[k] = radius[k] * t, angle
        # Segments: (kind, start time, duration, data); lines (p0, v), arcs (centre, r, phi0, omega).
        self._segments: list[tuple[str, float, float, tuple]] = []
        t0 = 0.0
        for k in range(n):
            if cut[k] > 0:
                a, b = u[k - 1], u[k]
                side = math.copysign(1.0, turn[k])                          # +1: a left turn
                normal = np.array([-a[1], a[0]]) * side
                start = self.points[k] - a * cut[k]
                centre = start + normal * radius[k]
                phi0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
                omega = side * speeds[k] / radius[k]
                dur = abs(turn[k]) * radius[k] / speeds[k]
                self._segments.append(('arc', t0, dur, (centre, radius[k], phi0, omega)))
                t0 += dur
            length = lengths[k] - cut[k] - cut[(k + 1) % n]
            p0 = self.points[k] + u[k] * cut[k]
            dur = length / speeds[k]
            self._segments.append(('line', t0, dur, (p0, u[k] * speeds[k])))
            t0 += dur
        self.starts = np.array([seg[1] for seg in self._segments])
        self.period = t0

    def state(self, t: float) -> np.ndarray:
        t = max(0.0, float(t)) % self.period
        k = int(np.searchsorted(self.starts, t, side='right')) - 1
        kind, start, _, data = self._segments[k]
        dt = t - start
        if kind == 'line':
            p0, v = data
            p = p0 + v * dt
            return np.array([p[0], p[1], v[0], v[1]])
        centre, r, phi0, omega = data
        phi = phi0 + omega * dt
        c, s = math.cos(phi), math.sin(phi)
        return np.array([centre[0] + r * c, centre[1] + r * s, -r * omega * s, r * omega * c])


class RelativeTrajectory(Trajectory):
    """A path ``local`` given in the frame of a moving ``platform`` (x along its heading), in the world frame.

    The velocity is the derivative of the world position (central difference over 1 ms); the heading
    the direction of motion.
    """

    def __init__(self, platform: Trajectory, local: Trajectory) -> None:
        self.platform, self.local = platform, local

    def _position(self, t: float) -> np.ndarray:
        p, q, yaw = self.platform.state(t), self.local.state(t), self.platform.heading(t)
        c, s = math.cos(yaw), math.sin(yaw)
        return np.array([p[0] + c * q[0] - s * q[1], p[1] + s * q[0] + c * q[1]])

    def state(self, t: float) -> np.ndarray:
        t = max(0.0, float(t))
        h = 1e-3
        v = (self._position(t + h) - self._position(max(0.0, t - h))) / (t + h - max(0.0, t - h))
        p = self._position(t)
        return np.array([p[0], p[1], v[0], v[1]])
