"""Stand-ins for the outside drivers of an application (paper §4.2: the Driver is what changes
between simulation and hardware): every Driver whose kind talks to another process (``ros2_control``:
a controller's command topic and ``joint_states``) gets the process its kind names
(:meth:`itasc_drivers.drivers.Driver.stand_in`), with the robot's joints where the model starts
them, so that a benchmark runs such an application on a machine without that driver.

    with StandIns(app, rate=1000.0):
        ...  # the application runs against them
"""

from __future__ import annotations

import signal
import subprocess
import tempfile

import numpy as np

__all__ = ['StandIns', 'initial_positions', 'stand_in_commands']


def initial_positions(driver, robot) -> dict[str, float]:
    """Where ``driver`` starts the joints of ``robot`` (a :class:`DrivenRobot`): its ``initial``
    if its kind has one, else 0, within the joint limits."""
    given = getattr(driver, 'initial', None) or {}
    return {joint: float(np.clip(given.get(joint, 0.0), lower, upper))
            for joint, lower, upper in zip(robot.joints, robot.limits['lower'], robot.limits['upper'])}


def stand_in_commands(app, *, rate: float) -> list[list[str]]:
    """The command line of every stand-in application ``app`` (``load_application``) needs, its
    drivers running at ``rate``."""
    from itasc_bringup.model.checks import driven_robot

    robots = {r.name: r for r in app.program.robots}
    commands = []
    for driver in app.drivers:
        robot = driven_robot(robots[driver.robot], rate)
        command = driver.driver.stand_in(driver, robot=robot, initial=initial_positions(driver, robot))
        if command is not None:
            commands.append(command)
    return commands


class StandIns:
    """The stand-in processes of an application, for the length of a ``with`` block; a model
    without a program (a composition model) has none."""

    def __init__(self, app, *, rate: float, env: dict[str, str] | None = None) -> None:
        self.commands = stand_in_commands(app, rate=rate) if app is not None else []
        self._env = env
        self.processes: list[subprocess.Popen] = []
        self._logs: list = []

    def __enter__(self) -> 'StandIns':
        for command in self.commands:  # stderr to a file: a full pipe would stop a chatty driver
            log = tempfile.TemporaryFile(mode='w+')
            self._logs.append(log)
            self.processes.append(subprocess.Popen(command, env=self._env, stdout=subprocess.DEVNULL, stderr=log))
        return self

    def died(self) -> list[str]:
        """What each stand-in that ended by itself said (an outside driver does not end)."""
        said = []
        for process, log in zip(self.processes, self._logs):
            if process.poll() is not None:
                log.seek(0)
                said.append(f'{" ".join(process.args[2:3])} ended (exit {process.returncode}): {log.read()[-2000:]}')
        return said

    def __exit__(self, *exc) -> None:
        for process in self.processes:
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        for process in self.processes:
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        for log in self._logs:
            log.close()
