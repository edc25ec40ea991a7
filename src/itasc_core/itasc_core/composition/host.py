"""A process hosting one composite (``--deploy per-composite``, paper §4.4 and §6.1).

Started by the parent's Composer (forked from its process's zygote, :mod:`.zygote`); does for
its composite what the bootstrap does for the root: brings up its Coordinator, Composer and
Configurator, then lets the life-cycle run. Its Scheduler is triggered over the composite's trigger
topic; while the composite runs, the thread that waits for the triggers and ticks has a real-time
priority where permitted (:mod:`.realtime`). The process ends after its Coordinator notified the
parent that it stopped (exit 0), or when the parent process is gone (exit 1): a composite whose
parent died can never be stopped in order, and must not outlive it. SIGINT and SIGTERM are ignored:
a terminal's Ctrl-C and a process manager's stop reach every process of the application, and the
bootstrap answers them with an orderly Stop of the whole hierarchy, which this process must stay
alive to take part in. Its parent ends it with SIGKILL when it cannot stop in order.
"""

from __future__ import annotations

import argparse
import contextlib
import faulthandler
import json
import os
import select
import signal
import time
from typing import Callable

import rclpy
from rclpy.signals import SignalHandlerOptions

from ..communication.dds import configure_dds, send_from_a_dds_thread
from ..entity import CompositeContext
from .composer import bring_up
from .deployment import Runtime, make_executor, end_process_within
from .realtime import ThreadPriority, priority_from_env
from .zygote import zygote_for
from .model import CompositeModel

#: Time to let the last events (e_<c>_stopped) reach the parent before the process exits.
LINGER = 0.5
#: How often the process looks whether its parent is gone and its composite stopped [s].
CHECK_PERIOD = 0.05


def parent_gone(pid: int) -> Callable[[], bool]:
    """A check whether process ``pid`` has ended. Not ``os.getppid() != pid``: a process forked by
    a zygote is the child of the zygote's intermediate process until that one has exited, and on a
    loaded machine that came after the composite's bring-up, which then took itself for orphaned."""
    try:
        pidfd = os.pidfd_open(pid)  # readable once the process has ended
    except ProcessLookupError:
        return lambda: True
    return lambda: bool(select.select([pidfd], [], [], 0)[0])


def _ticks(state: str) -> bool:
    """Whether a composite in ``state`` ticks: Running, and Safety too (each tick makes its entities
    safe, a Driver commanding zero), not the bring-up's or the stop's work."""
    return state.startswith(('Active.Run', 'Safety'))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--spec', required=True)
    parser.add_argument('--namespace', required=True)
    parser.add_argument('--parent-namespace', required=True)
    parser.add_argument('--parent-pid', type=int, required=True)
    args = parser.parse_args(argv)
    with open(args.spec) as spec:
        model = CompositeModel.model_validate(json.load(spec))
    with contextlib.suppress(OSError):  # read once: nothing is left in the temporary folder if a parent is killed
        os.unlink(args.spec)
    context = CompositeContext(name=model.name, namespace=args.namespace, parent_namespace=args.parent_namespace)

    configure_dds()
    send_from_a_dds_thread()
    faulthandler.register(signal.SIGUSR1, all_threads=True)  # `kill -USR1 <pid>`: where is it stuck?
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_IGN)
    zygote = zygote_for(model)  # before DDS starts threads
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    runtime = Runtime(executor=executor, mode='per-composite', namespace=args.namespace, background=True,
                      zygote=zygote)
    orphaned = parent_gone(args.parent_pid)
    composer = bring_up(model=model, context=context, runtime=runtime, remote_trigger=True)
    priority = ThreadPriority(priority_from_env(), refused=composer.get_logger().info)
    stopped_at = None
    looked_at = 0.0
    try:
        while True:
            executor.spin_once(timeout_sec=CHECK_PERIOD)
            runtime.reap()
            now = time.monotonic()
            if now - looked_at < CHECK_PERIOD:
                continue  # a spin runs one callback: not a look at the parent and the state per message
            looked_at = now
            priority.realtime(_ticks(composer.coordinator.state))
            if orphaned():
                composer.get_logger().error(f'parent process {args.parent_pid} is gone; {model.name} ends')
                break
            if stopped_at is None and composer.coordinator.state.endswith('NotifyStopped'):
                stopped_at = now
            if stopped_at is not None and now - stopped_at > LINGER:
                break
    finally:
        priority.realtime(False)
        runtime.shutdown(orderly=stopped_at is not None)
        end_process_within()
        runtime.reap(wait=True)
        for node in (composer.coordinator, composer.configurator, composer):
            executor.remove_node(node)
            node.destroy_node()
        rclpy.try_shutdown()
    return 0 if stopped_at is not None else 1


if __name__ == '__main__':
    raise SystemExit(main())
