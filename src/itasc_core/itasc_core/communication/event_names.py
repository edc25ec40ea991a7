"""The vocabulary of event names (paper §3.1 boundary of knowledge, §6.1 Figs. 4-6, §7.2): every
event name of the runtime is built here, from one rule and the words below.

The rule: an event about an owner (a composite, a Task, a Monitor, a robot) is ``e_<owner>_<what>``,
e.g. ``e_ApproachObject_configured``. A parent commands a child composite on its own event topic
(``e_<child>_configure``) and the child answers there (``e_<child>_configured``); a Coordinator
commands its own entities on its composite's topic (``e_<c>_deploy`` -> ``e_<c>_deployed``). The
child's Coordinator either reacts to a command in its own life-cycle FSM, or passes it into its
composite as ``e_<x>`` (:func:`from_parent`), where its own entities (Configurator, Scheduler) react.
A parent knows its children, never their insides; and since the prefix is the child's name, an
event meant for one child never reaches another.

Priority events (processed on arrival, §6.2): ``e_emergency`` and the command that puts a child
into Safety, ``e_<child>_emergency``.
"""

from __future__ import annotations

__all__ = [
    'SAFETY_EVENT', 'STOP_REQUESTED', 'event', 'named', 'compose_step', 'step_of', 'solver_status', 'to_child',
    'from_parent',
    'is_addressed_to', 'is_priority', 'owner_of',
    # life cycle: commands of a parent and notifications of a child (Figs. 4, 5)
    'CONFIGURE', 'START', 'RUN', 'STOP', 'EMERGENCY', 'CONFIGURED', 'STARTED', 'RUNNING', 'STOPPED', 'TIMEOUT',
    'NOTIFICATIONS',
    # a Coordinator and its own entities (Fig. 6): Composer, Configurator, Scheduler
    'DEPLOY', 'DEPLOYED', 'DEPLOY_FAILED', 'CONFIGURE_ENTITIES', 'ENTITIES_CONFIGURED', 'CONFIGURE_FAILED',
    'CONNECT', 'CONNECTED', 'CONNECT_FAILED', 'CONNECTION_REFUSED', 'SCHEDULER_INITIALIZE', 'SCHEDULER_INITIALIZED',
    'SCHEDULER_ACTIVATE', 'SCHEDULER_ACTIVATED', 'SCHEDULER_FAILED', 'DISENGAGE', 'DISENGAGED',
    'CLEANUP_COMPUTATION', 'COMPUTATION_CLEANED', 'CLEANUP', 'CLEANED', 'SAFETY', 'COMPOSED', 'COMPOSE_FAILED',
    'CHILD_ADDED', 'CHILD_REMOVED', 'BIND', 'CHECK_FAULTS', 'FAULTS_CHECKED', 'RECOVERING', 'ANSWERS',
    # entities switched by the Coordinator, configurations, robots
    'ACTIVATE', 'DEACTIVATE', 'ON', 'OFF', 'APPLIED', 'FAILED', 'PARAMETER_SET', 'PARAMETER_REFUSED', 'JOINTS_MISSING',
    'NOTHING_RECEIVED', 'SOLVER_STATUSES', 'LIFE_CYCLE',
]

#: The event that puts a composite (and its parent, where the application says so) into Safety.
SAFETY_EVENT = 'e_emergency'
#: An operator's ``~/stop``, travelling up to the root.
STOP_REQUESTED = 'e_stop_requested'

# -- life cycle (Figs. 4, 5): a parent's commands to a child, the child's notifications -------------
CONFIGURE, START, RUN, STOP = 'configure', 'start', 'run', 'stop'
#: The parent entered Safety: so does the child.
EMERGENCY = 'emergency'
CONFIGURED, STARTED, RUNNING, STOPPED = 'configured', 'started', 'running', 'stopped'
NOTIFICATIONS = (CONFIGURED, STARTED, RUNNING, STOPPED)
#: A state on the way to Running waited too long.
TIMEOUT = 'timeout'

# -- a Coordinator's commands to its own entities and their answers (Fig. 6) ------------------------
DEPLOY, DEPLOYED, DEPLOY_FAILED = 'deploy', 'deployed', 'deploy_failed'
CONFIGURE_ENTITIES, ENTITIES_CONFIGURED, CONFIGURE_FAILED = 'configure_entities', 'entities_configured', \
    'configure_failed'
CONNECT, CONNECTED, CONNECT_FAILED = 'connect', 'connected', 'connect_failed'
CONNECTION_REFUSED = 'connection_refused'
SCHEDULER_INITIALIZE, SCHEDULER_INITIALIZED = 'scheduler_initialize', 'scheduler_initialized'
SCHEDULER_ACTIVATE, SCHEDULER_ACTIVATED = 'scheduler_activate', 'scheduler_activated'
SCHEDULER_FAILED = 'scheduler_failed'
DISENGAGE, DISENGAGED = 'disengage', 'disengaged'
CLEANUP_COMPUTATION, COMPUTATION_CLEANED = 'cleanup_computation', 'computation_cleaned'
CLEANUP, CLEANED = 'cleanup', 'cleaned'
#: Safety entered: the Scheduler brings the outputs to safe values.
SAFETY = 'safety'
#: A Composer's answers to a composition step (``e_<c>_compose_<step>``, :func:`compose_step`).
COMPOSED, COMPOSE_FAILED = 'composed', 'compose_failed'
#: A Composer tells its Coordinator of a child composite added or removed while running (detail: its name).
CHILD_ADDED, CHILD_REMOVED = 'child_added', 'child_removed'
#: A parent asks a child's Composer to connect the inside of an exported input.
BIND = 'bind'
#: Before a recovery from Safety (:mod:`itasc_core.coordination.recovery`).
CHECK_FAULTS, FAULTS_CHECKED, RECOVERING = 'check_faults', 'faults_checked', 'recovering'
#: A Coordinator's commands to its own Composer, Configurator and Scheduler, and their answers (both
#: ``e_<composite>_<word>``).
ANSWERS = {
    DEPLOY: (DEPLOYED, DEPLOY_FAILED),
    CONFIGURE_ENTITIES: (ENTITIES_CONFIGURED, CONFIGURE_FAILED),
    CONNECT: (CONNECTED, CONNECT_FAILED),
    SCHEDULER_INITIALIZE: (SCHEDULER_INITIALIZED,),
    SCHEDULER_ACTIVATE: (SCHEDULER_ACTIVATED,),
    DISENGAGE: (DISENGAGED,),
    CLEANUP_COMPUTATION: (COMPUTATION_CLEANED,),
    CLEANUP: (CLEANED,),
}

# -- entities switched by the Coordinator, named configurations, robots, the Solver -----------------
#: A scheduled entity or child composite switched on and off (``e_<entity>_activate``).
ACTIVATE, DEACTIVATE = 'activate', 'deactivate'
#: A Monitor switched on and off (``e_<monitor>_on``).
ON, OFF = 'on', 'off'
#: A Configurator's answer to configuration ``e_<configuration>``: ``e_<configuration>_applied``.
APPLIED, FAILED = 'applied', 'failed'
#: A parameter of an entity changed (``e_<entity>_parameter_set``, detail ``kp: 1.0 -> 2.0 (<cause>)``),
#: or a change was refused (detail: why).
PARAMETER_SET, PARAMETER_REFUSED = 'parameter_set', 'parameter_refused'
#: A robot's Driver does not report some of its joints (``e_<robot>_joints_missing``).
JOINTS_MISSING = 'joints_missing'
#: A Monitor of the arrival of data stopped having watched its input for longer than its timeout with
#: nothing ever coming (``e_<monitor>_nothing_received``): the run ended within its grace for a first sample.
NOTHING_RECEIVED = 'nothing_received'
#: What the Solver reports as ``e_solver_<status>``.
SOLVER_STATUSES = ('ok', 'singular', 'infeasible', 'saturated')

#: What the runtime says to and of a composite (``e_<composite>_<word>``): the life cycle's commands
#: and answers, a Coordinator's to its own entities, a composition's, a recovery's, a child switched
#: on or off. An application model raises none of them, nor names a configuration after one (a
#: configuration ``stop`` would be commanded to a Task as ``e_<Task>_stop``).
LIFE_CYCLE = (CONFIGURE, START, RUN, STOP, EMERGENCY, *NOTIFICATIONS, TIMEOUT, *ANSWERS,
              *(answer for answers in ANSWERS.values() for answer in answers), CONNECTION_REFUSED,
              SCHEDULER_FAILED, SAFETY, COMPOSED, COMPOSE_FAILED, CHILD_ADDED, CHILD_REMOVED, BIND, CHECK_FAULTS,
              FAULTS_CHECKED, RECOVERING, ACTIVATE, DEACTIVATE)


def event(owner: str, what: str) -> str:
    """``e_<owner>_<what>``: the event ``what`` (one of the words above) of ``owner``."""
    return f'e_{owner}_{what}'


def named(name: str) -> str:
    """``e_<name>``: an event named by the model, e.g. a named configuration's."""
    return f'e_{name}'


def compose_step(composite: str, step: str) -> str:
    """The command that makes ``composite``'s Composer execute composition step ``step``."""
    return event(composite, f'compose_{step}')


def step_of(composite: str, name: str) -> str | None:
    """The composition step the command ``name`` = ``e_<composite>_compose_<step>`` names, None if
    it is none (``e_<composite>_compose_failed`` is an answer)."""
    prefix = compose_step(composite, '')
    if not name.startswith(prefix) or name == event(composite, COMPOSE_FAILED):
        return None
    return name[len(prefix):] or None


def solver_status(status: str) -> str:
    return event('solver', status)


def to_child(child: str, event_name: str) -> str:
    """The name under which a parent commands ``event_name`` (``e_<x>`` or ``<x>``) to ``child``."""
    return event(child, event_name.removeprefix('e_'))


def is_addressed_to(child: str, name: str) -> bool:
    return name.startswith(f'e_{child}_')


def from_parent(child: str, name: str) -> str:
    """The event a parent's command ``e_<child>_<x>`` becomes inside ``child``: ``e_<x>``."""
    return named(name.removeprefix(f'e_{child}_'))


def owner_of(name: str, what: str) -> str | None:
    """The owner of ``e_<owner>_<what>``, None if ``name`` is not such an event."""
    if name.startswith('e_') and name.endswith(f'_{what}') and len(name) > len(what) + 3:
        return name[2:-len(what) - 1]
    return None


def is_priority(name: str) -> bool:
    return name == SAFETY_EVENT or name.endswith(f'_{EMERGENCY}')
