"""Setpoint Generators (paper §4.1): desired values for a Task's controller.

Each generator is called with the time t and returns ``(value, velocity)``: the setpoint and its
velocity feed-forward. Values are numpy vectors (output space of the Task) or ``pin.SE3`` (a
Cartesian target: the desired pose of o2 in o1); for SE3 the velocity is the 6-D twist
``[d/dt p ; omega]`` in o1 coordinates, matching ``CartesianVKC`` rows. Point-to-point
generators interpolate position linearly and orientation along the geodesic (exp/log on SO(3)).
A generator that is not ``started`` is started by its Task from the current output
(:func:`start_value`; a point-to-point motion and ``HoldSetpoint`` again whenever the Task is
activated); :class:`OutputSetpoint` turns what it gives into output space, the same for
the Setpoint Generator entity and :class:`~itasc_tasks.task.TaskComputation`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol, TypeAlias

import numpy as np
import pinocchio as pin
from itasc_core.itasc.coordinates import features_pose, pose_coordinates, pose_features

from .constraint_output import Selection

__all__ = ['SetpointGenerator', 'Value', 'FixedSetpoint', 'HoldSetpoint', 'PointToPoint', 'MinimumJerkSetpoint',
           'TrapezoidalSetpoint', 'PeriodicSetpoint', 'TopicSetpoint', 'OutputSetpoint', 'start_value']

#: A vector in output space, or a ``pin.SE3`` (pinocchio has no type information: Any to mypy).
Value: TypeAlias = np.ndarray | Any


class SetpointGenerator(Protocol):
    """What a Task needs from a setpoint generator."""

    @property
    def started(self) -> bool:
        """Whether it was started (else its Task starts it, :func:`start_value`)."""

    def start(self, value: Value, t: float) -> None: ...

    def __call__(self, t: float) -> tuple[Value, np.ndarray]: ...


def _as_value(value: Value | Sequence[float] | float) -> Value:
    return pin.SE3(value) if isinstance(value, pin.SE3) else np.atleast_1d(
        np.asarray(value, dtype=float)).copy()


def _zero_velocity(value: Value) -> np.ndarray:
    return np.zeros(6) if isinstance(value, pin.SE3) else np.zeros_like(value)


class FixedSetpoint:
    """A constant setpoint."""

    started = True

    def __init__(self, value: Value | Sequence[float] | float) -> None:
        self.value = _as_value(value)
        self._velocity = _zero_velocity(self.value)

    def start(self, value: Value, t: float) -> None:
        """Nothing to start: the setpoint is fixed."""

    def __call__(self, t: float) -> tuple[Value, np.ndarray]:
        return self.value, self._velocity


class HoldSetpoint(FixedSetpoint):
    """Holds the output where the Task was when it started the generator (each time it does)."""

    def __init__(self) -> None:
        super().__init__(np.zeros(0))
        self.started = False

    def start(self, value: Value, t: float) -> None:
        self.value = _as_value(value)
        self._velocity = _zero_velocity(self.value)
        self.started = True


class PointToPoint:
    """Smooth motion from the start value to ``target`` along a scalar profile s(t) in [0, 1]."""

    def __init__(self, target: Value | Sequence[float] | float, *, duration: float = 0.0,
                 max_velocity: float | Sequence[float] | None = None) -> None:
        """``duration``: minimum duration [s]; ``max_velocity``: per component (vector target)
        or ``(linear, angular)`` (SE3 target); the motion lasts the longest of the two."""
        self.target = _as_value(target)
        self.duration = duration
        self.max_velocity = max_velocity
        self.started = False
        self._from: Value = self.target
        self._t0 = 0.0
        self._delta = np.zeros(0)  # vector: target - start; SE3: [dp, log3(R0^T R1)]
        self._twist = np.zeros(0)
        self.period = 0.0  # actual duration of the current motion

    def restart(self) -> None:
        """The Task restarts the motion to the same target from the current output."""
        self.started = False

    def start(self, value: Value, t: float) -> None:
        self._from, self._t0, self.started = _as_value(value), t, True
        if isinstance(self.target, pin.SE3):
            a, b = self._from, self.target
            self._delta = np.concatenate([b.translation - a.translation,
                                          pin.log3(a.rotation.T @ b.rotation)])
            self._twist = np.concatenate([self._delta[:3], a.rotation @ self._delta[3:]])  # of o2 in o1, per unit of s
            lengths = np.array([np.linalg.norm(self._delta[:3]), np.linalg.norm(self._delta[3:])])
        else:
            self._delta = self.target - self._from
            lengths = np.abs(self._delta)
        self.period = self._period(lengths)

    def _normalised_limit(self, lengths: np.ndarray, limit: float | Sequence[float] | None) -> float:
        """The tightest path-parameter rate allowed by per-component limits (None: unlimited)."""
        if limit is None:
            return math.inf
        limits = np.broadcast_to(np.asarray(limit, dtype=float), lengths.shape)
        moving = lengths > 1e-12
        return float(np.min(limits[moving] / lengths[moving])) if moving.any() else math.inf

    def _period(self, lengths: np.ndarray) -> float:
        raise NotImplementedError

    def _profile(self, t: float) -> tuple[float, float]:
        raise NotImplementedError

    def __call__(self, t: float) -> tuple[Value, np.ndarray]:
        s, sdot = self._profile(t - self._t0) if self.period > 0.0 else (1.0, 0.0)
        if isinstance(self._from, pin.SE3):
            a, d = self._from, self._delta
            pose = pin.SE3(a.rotation.dot(pin.exp3(s * d[3:])), a.translation + s * d[:3])
            return pose, sdot * self._twist
        return self._from + s * self._delta, sdot * self._delta


class MinimumJerkSetpoint(PointToPoint):
    """Minimum-jerk point-to-point motion, s = 10 tau^3 - 15 tau^4 + 6 tau^5 (peak velocity
    1.875 x the mean), time-bounded (``duration``) and/or velocity-bounded (``max_velocity``)."""

    def _period(self, lengths: np.ndarray) -> float:
        rate = math.inf if self.max_velocity is None else self._normalised_limit(
            lengths, self.max_velocity)
        return max(self.duration, 1.875 / rate if rate < math.inf else 0.0)

    def _profile(self, t: float) -> tuple[float, float]:
        tau = min(max(t / self.period, 0.0), 1.0)
        s = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        sdot = 30.0 * tau * tau * (1.0 - tau) ** 2 / self.period
        return s, sdot


class TrapezoidalSetpoint(PointToPoint):
    """Trapezoidal-velocity point-to-point motion with per-component ``max_velocity`` and
    ``max_acceleration``, stretched (same acceleration, lower cruise speed) to ``duration``."""

    def __init__(self, target: Value | Sequence[float] | float, *,
                 max_velocity: float | Sequence[float] = 1.0,
                 max_acceleration: float | Sequence[float] = 1.0, duration: float = 0.0) -> None:
        super().__init__(target, duration=duration, max_velocity=max_velocity)
        self.max_acceleration = max_acceleration
        self._acc = self._cruise = 0.0

    def _period(self, lengths: np.ndarray) -> float:
        v = self._normalised_limit(lengths, self.max_velocity)
        a = self._normalised_limit(lengths, self.max_acceleration)
        if math.isinf(v) or math.isinf(a):
            return 0.0
        shortest = 2.0 / math.sqrt(a) if v * v >= a else 1.0 / v + v / a
        period = max(self.duration, shortest)
        self._acc = a
        self._cruise = (a * period - math.sqrt(max(a * a * period * period - 4.0 * a, 0.0))) / 2
        return period

    def _profile(self, t: float) -> tuple[float, float]:
        a, v, T = self._acc, self._cruise, self.period
        ta = v / a
        if t <= 0.0:
            return 0.0, 0.0
        if t < ta:
            return 0.5 * a * t * t, a * t
        if t < T - ta:
            return 0.5 * a * ta * ta + v * (t - ta), v
        if t < T:
            return 1.0 - 0.5 * a * (T - t) ** 2, a * (T - t)
        return 1.0, 0.0


class PeriodicSetpoint:
    """A sinusoid ``offset + amplitude sin(2 pi t / period + phase)`` (vectors broadcast)."""

    started = True

    def __init__(self, *, amplitude: float | Sequence[float], period: float,
                 offset: float | Sequence[float] = 0.0, phase: float | Sequence[float] = 0.0
                 ) -> None:
        self.amplitude = np.atleast_1d(np.asarray(amplitude, dtype=float))
        self.offset = np.atleast_1d(np.asarray(offset, dtype=float))
        self.phase = np.atleast_1d(np.asarray(phase, dtype=float))
        self.period = period

    def start(self, value: Value, t: float) -> None:
        """Nothing to start: the sinusoid is a function of absolute time."""

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        w = 2.0 * math.pi / self.period
        angle = w * t + self.phase
        value = self.offset + self.amplitude * np.sin(angle)
        return value, np.broadcast_to(self.amplitude * w * np.cos(angle), value.shape).copy()


class TopicSetpoint:
    """Holds the last value pushed into it (from a topic); holds the current output until the
    first value arrives."""

    def __init__(self, value: Value | Sequence[float] | float | None = None) -> None:
        self.value: Value | None = None if value is None else _as_value(value)
        self.velocity: np.ndarray | None = None

    @property
    def started(self) -> bool:
        return self.value is not None

    def push(self, value: Value | Sequence[float] | float,
             velocity: Sequence[float] | None = None) -> None:
        self.value = _as_value(value)
        self.velocity = None if velocity is None else np.asarray(velocity, dtype=float)

    def start(self, value: Value, t: float) -> None:
        self.value = _as_value(value)

    def __call__(self, t: float) -> tuple[Value, np.ndarray]:
        assert self.value is not None, 'TopicSetpoint called before any value'
        return self.value, _zero_velocity(self.value) if self.velocity is None else self.velocity


def start_value(generator: SetpointGenerator, *, features: np.ndarray, output: np.ndarray,
                rotation: int | None) -> Value:
    """Where ``generator`` starts from: for a pose target the current pose of o2 in o1 (from the
    chain's ``features``, a rotation triple at row ``rotation`` or log6), else the current ``output``."""
    if isinstance(generator, PointToPoint) and isinstance(generator.target, pin.SE3):
        return features_pose(features, coordinates=pose_coordinates(rotation))
    return output


class OutputSetpoint:
    """A generator's ``(value, velocity)`` in output space: a pose of o2 in o1 and its twist through
    the chain's pose coordinates (rotation triple at row ``rotation``, or log6), then the Constraint
    Output's selection; a vector is already in output space. A fixed pose is converted once."""

    def __init__(self) -> None:
        self._pose: Any = None
        self._rotation: int | None = None
        self._features = np.zeros(0)

    def __call__(self, value: Value, velocity: np.ndarray, *, selection: Selection,
                 rotation: int | None) -> tuple[np.ndarray, np.ndarray]:
        if isinstance(value, np.ndarray):
            return value, velocity
        if value is not self._pose or rotation != self._rotation:
            self._pose, self._rotation = value, rotation
            self._features = pose_features(value, coordinates=pose_coordinates(rotation))
        return selection.select(self._features), selection.select(velocity)
