"""A process hosting one composite (``--deploy per-composite``, paper §4.4 and §6.1).

Started by the parent's Composer (forked from its process's zygote, :mod:`.zygote`); does for
its composite what the bootstrap does for the root: brings up its Coordinator, Composer and
Configurator, then lets the life-cycle run. Its Scheduler is triggered over the composite's trigger
topic; while the composite runs, the thread that waits for the triggers and ticks has a real-time
priority where permitted (:mod:`.realtime`). The process ends after its Coordinator notified the
parent that it stopped (exit 0), or when the parent process is gone (exit 1): a composite whose
parent died can never be stopped in order, and must not outlive it. A recorded run's composite
process streams its outputs to the recording (``--record-to``, :mod:`..communication.sample_stream`),
and so do the composite processes it starts. SIGINT and SIGTERM are ignored:
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
import rclpy.logging
from rclpy.signals import SignalHandlerOptions

from ..communication.dds import configure_dds, send_from_a_dds_thread
from ..communication.sample_stream import SampleStream, abstract_address
from ..entity import CompositeContext
from .composer import bring_up
from .deployment import RecordTo, Runtime, make_executor, end_process_within
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


def _stream(runtime: Runtime, record_to: RecordTo) -> SampleStream | None:
    """The stream of this process's outputs to the recording, None (said) when its writer cannot be reached."""
    logger = rclpy.logging.get_logger('recording')
    try:
        return SampleStream(runtime.bus, address=abstract_address(record_to.address), prefix=record_to.prefix,
                            on_broken=lambda: logger.error('the recording process is gone: the outputs of this '
                                                           'process are recorded no more'))
    except OSError as err:
        logger.error(f'the recording process cannot be reached ({err}): the outputs of this process are not recorded')
        return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--spec', required=True)
    parser.add_argument('--namespace', required=True)
    parser.add_argument('--parent-namespace', required=True)
    parser.add_argument('--parent-pid', type=int, required=True)
    parser.add_argument('--record-to', metavar='ADDRESS', default=None,
                        help="the recording writer's abstract Unix socket: stream this process's outputs there")
    parser.add_argument('--record-prefix', default='/', help='... those under this namespace')
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
    record_to = None if args.record_to is None else RecordTo(args.record_to, args.record_prefix)
    runtime = Runtime(executor=executor, mode='per-composite', namespace=args.namespace, background=True,
                      zygote=zygote, record_to=record_to)
    orphaned = parent_gone(args.parent_pid)
    stream = None if record_to is None else _stream(runtime, record_to)  # before the first output exists
    composer = bring_up(model=model, context=context, runtime=runtime, remote_trigger=True)
    priority = ThreadPriority(priority_from_env(), refused=composer.get_logger().info)
    stopped_at = None
    looked_at = 0.0
    try:
        while True:
            executor.spin_once(timeout_sec=CHECK_PERIOD)
            if stream is not None:
                stream.drain()  # the samples of the tick that just ran
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
        if stream is not None:
            stream.close()
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
