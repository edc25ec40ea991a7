"""Robot: the kinematic model of a robot with controllable DOF (paper §4.1 "Robots and Objects").

A URDF (file path or ``robot_description`` string) loaded with Pinocchio, optionally on a mobile
base that is part of the model (a planar or free-flyer root joint), placed in the world. Joint
state is addressed by name per *velocity coordinate* (what JointState and the Solver see); object
frames are attached to links with an offset; ``update()`` computes forward kinematics and all
joint Jacobians once per cycle, after which frame poses and Jacobians are cheap look-ups.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

__all__ = ['Robot', 'se3']

_INF_LIMIT = 1e20  # Pinocchio's "no limit" sentinel is ~1.8e308; anything above this is unbounded
_BASES = ('fixed', 'planar', 'free_flyer')


def se3(xyz: Sequence[float] = (0.0, 0.0, 0.0), rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> pin.SE3:
    """The SE3 placement given by a translation and roll-pitch-yaw angles (URDF convention)."""
    return pin.SE3(pin.rpy.rpyToMatrix(*map(float, rpy)), np.asarray(xyz, dtype=float))


class Robot:
    """Kinematic model of one robot (optionally a mobile base) placed in the world.

    Velocity coordinates (``joint_names``, ``positions``, limits, Jacobian columns) follow
    Pinocchio's tangent space: one per 1-DOF joint (continuous joints: the angle), ``x, y, theta``
    for a planar base (velocities in the base frame), ``x, y, z, roll, pitch, yaw`` positions /
    local linear + angular velocities for a free-flyer base.
    """

    def __init__(self, name: str, urdf: str | Path, *, base: str = 'fixed',
                 xyz: Sequence[float] = (0.0, 0.0, 0.0), rpy: Sequence[float] = (0.0, 0.0, 0.0),
                 prefix: str = '', lower: Mapping[str, float] | None = None,
                 upper: Mapping[str, float] | None = None,
                 velocity_limit: Mapping[str, float] | None = None) -> None:
        """Load ``urdf`` (a path, or the XML itself) with a ``base`` root joint.

        ``xyz``/``rpy`` place the robot's root in the world; ``prefix`` is prepended to URDF
        joint names (two identical robots in one Scene); ``lower``/``upper``/``velocity_limit``
        override URDF limits by joint name.
        """
        if base not in _BASES:
            raise ValueError(f'Robot {name!r}: base must be one of {_BASES}, got {base!r}')
        self.name, self.base = name, base
        root = {'fixed': None, 'planar': pin.JointModelPlanar(),
                'free_flyer': pin.JointModelFreeFlyer()}[base]
        text = str(urdf)
        build = pin.buildModelFromXML if text.lstrip().startswith('<') else pin.buildModelFromUrdf
        self.model: pin.Model = build(text) if root is None else build(text, root)
        self._place(se3(xyz, rpy))
        self._index_joints(prefix)
        self._read_limits()
        for values, target in ((lower, self.lower), (upper, self.upper),
                               (velocity_limit, self.velocity_limit)):
            for joint, value in (values or {}).items():
                target[self._index(joint)] = float(value)
        self.q = pin.neutral(self.model)
        self.data = self.model.createData()
        self._frame_ids: dict[str, int] = {}

    # -- construction -------------------------------------------------------------------------
    def _place(self, placement: pin.SE3) -> None:
        """Put the robot root at ``placement`` in the world by re-parenting what hangs on it."""
        for j in range(1, self.model.njoints):
            if self.model.parents[j] == 0:
                self.model.jointPlacements[j] = placement * self.model.jointPlacements[j]
        for f in range(1, len(self.model.frames)):
            frame = self.model.frames[f]
            if frame.parentJoint == 0:
                frame.placement = placement * frame.placement
                self.model.frames[f] = frame

    def _index_joints(self, prefix: str) -> None:
        names: list[str] = []
        simple_q, simple_v, circle_q, circle_v = [], [], [], []
        for j in range(1, self.model.njoints):
            joint = self.model.joints[j]
            iq, iv = joint.idx_q, joint.idx_v
            if j == 1 and self.base != 'fixed':
                coords = ('x', 'y', 'theta') if self.base == 'planar' else (
                    'x', 'y', 'z', 'roll', 'pitch', 'yaw')
                names += [f'{self.name}_base_{c}' for c in coords]
            elif joint.nq == 1 and joint.nv == 1:
                names.append(prefix + self.model.names[j])
                simple_q.append(iq)
                simple_v.append(iv)
            elif joint.nq == 2 and joint.nv == 1:
                names.append(prefix + self.model.names[j])
                circle_q.append(iq)
                circle_v.append(iv)
            else:
                raise ValueError(f'Robot {self.name!r}: joint {self.model.names[j]!r} '
                                 f'({joint.shortname()}) is not supported')
        self.joint_names: list[str] = names
        self.nq, self.nv = self.model.nq, self.model.nv
        self._simple = (np.array(simple_q, dtype=int), np.array(simple_v, dtype=int))
        self._circle = (np.array(circle_q, dtype=int), np.array(circle_v, dtype=int))
        self._vindex = {n: i for i, n in enumerate(names)}
        self._base_nv = 0 if self.base == 'fixed' else self.model.joints[1].nv
        # a fixed base and 1-DOF joints with q in velocity order: positions are q itself
        self._plain = self.base == 'fixed' and not circle_q and simple_q == simple_v == list(range(self.model.nv))

    def _read_limits(self) -> None:
        m = self.model
        lo, hi = np.full(self.nv, -np.inf), np.full(self.nv, np.inf)
        sq, sv = self._simple
        limited = (m.lowerPositionLimit[sq] < m.upperPositionLimit[sq]) & (
            m.upperPositionLimit[sq] < _INF_LIMIT)
        lo[sv[limited]] = m.lowerPositionLimit[sq[limited]]
        hi[sv[limited]] = m.upperPositionLimit[sq[limited]]
        vel = np.array(m.velocityLimit, dtype=float)
        vel[(vel <= 0.0) | (vel >= _INF_LIMIT)] = np.inf
        self.lower, self.upper, self.velocity_limit = lo, hi, vel
        #: Joints whose URDF limits are crossed (lower above upper): taken as unlimited above, a
        #: URDF error that the model check refuses.
        self.crossed_limits = [self.joint_names[v] for q, v in zip(sq, sv)
                               if m.lowerPositionLimit[q] > m.upperPositionLimit[q]]

    def _index(self, joint: str) -> int:
        try:
            return self._vindex[joint]
        except KeyError:
            raise KeyError(f'Robot {self.name!r} has no joint {joint!r}; '
                           f'joints: {self.joint_names}') from None

    def add_frame(self, name: str, link: str, *, xyz: Sequence[float] = (0.0, 0.0, 0.0),
                  rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Attach an object frame ``name`` to ``link`` (any existing frame) with an offset."""
        if self.model.existFrame(name):
            raise ValueError(f'Robot {self.name!r} already has a frame {name!r}')
        if not self.model.existFrame(link):
            raise KeyError(f'Robot {self.name!r} has no link {link!r}')
        parent_id = self.model.getFrameId(link)
        parent = self.model.frames[parent_id]
        self.model.addFrame(pin.Frame(name, parent.parentJoint, parent_id,
                                      parent.placement * se3(xyz, rpy), pin.FrameType.OP_FRAME))
        self.data = self.model.createData()
        self._frame_ids.clear()

    # -- state ----------------------------------------------------------------------------------
    @property
    def positions(self) -> np.ndarray:
        """Positions per velocity coordinate, in ``joint_names`` order."""
        if self._plain:
            return self.q.copy()
        out = np.empty(self.nv)
        sq, sv = self._simple
        out[sv] = self.q[sq]
        cq, cv = self._circle
        out[cv] = np.arctan2(self.q[cq + 1], self.q[cq])
        if self.base == 'planar':
            out[:3] = self.q[0], self.q[1], np.arctan2(self.q[3], self.q[2])
        elif self.base == 'free_flyer':
            out[:3] = self.q[:3]
            out[3:6] = pin.rpy.matrixToRpy(pin.Quaternion(self.q[3:7]).toRotationMatrix())
        return out

    def set_position_vector(self, positions: np.ndarray) -> None:
        """Set all positions from a vector per velocity coordinate (``joint_names`` order)."""
        if self._plain:
            self.q[:] = positions
            return
        sq, sv = self._simple
        self.q[sq] = positions[sv]
        cq, cv = self._circle
        self.q[cq], self.q[cq + 1] = np.cos(positions[cv]), np.sin(positions[cv])
        if self.base == 'planar':
            x, y, theta = positions[:3]
            self.q[:4] = x, y, np.cos(theta), np.sin(theta)
        elif self.base == 'free_flyer':
            self.q[:3] = positions[:3]
            quat = pin.Quaternion(pin.rpy.rpyToMatrix(*positions[3:6]))
            self.q[3:7] = quat.coeffs()

    def set_positions(self, names: Iterable[str], values: Iterable[float]) -> None:
        """Set positions by joint name (any order; names of other robots are ignored)."""
        p = self.positions
        index = self._vindex
        for n, v in zip(names, values):
            i = index.get(n)
            if i is not None:
                p[i] = v
        self.set_position_vector(p)

    def integrate(self, qdot: np.ndarray, dt: float) -> None:
        """Advance the configuration by the velocity ``qdot`` (per velocity coordinate) over dt."""
        self.q = pin.integrate(self.model, self.q, np.asarray(qdot, dtype=float) * dt)

    # -- kinematics -----------------------------------------------------------------------------
    def update(self) -> None:
        """Forward kinematics and all joint Jacobians for the current q (once per cycle)."""
        pin.computeJointJacobians(self.model, self.data, self.q)
        pin.updateFramePlacements(self.model, self.data)

    def frame_id(self, name: str) -> int:
        """Pinocchio id of a link or object frame (cached)."""
        fid = self._frame_ids.get(name)
        if fid is None:
            if not self.model.existFrame(name):
                raise KeyError(f'Robot {self.name!r} has no frame {name!r}')
            fid = self._frame_ids[name] = self.model.getFrameId(name)
        return fid

    def frame_pose(self, name: str) -> pin.SE3:
        """World pose of a frame (a copy), as of the last ``update()``."""
        return pin.SE3(self.data.oMf[self.frame_id(name)])

    def frame_jacobian(self, name: str) -> np.ndarray:
        """(6, nv) Jacobian of a frame, LOCAL_WORLD_ALIGNED: [linear velocity of the frame
        origin; angular velocity], both in world coordinates, as of the last ``update()``."""
        return pin.getFrameJacobian(self.model, self.data, self.frame_id(name),
                                    pin.LOCAL_WORLD_ALIGNED)
