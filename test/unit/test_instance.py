"""The bootstrap's one-instance lock (:mod:`itasc_bringup.instance`): held by one process per
application and ROS domain, released however that process ends, not inherited by its children."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import pytest
from itasc_bringup.instance import AlreadyRunning, InstanceLock

HOLD = textwrap.dedent('''
    import os, sys, time
    from itasc_bringup.instance import InstanceLock
    lock = InstanceLock('app', domain=7, directory=sys.argv[1])
    lock.acquire()
    if os.fork() == 0:  # a child forked as the zygote forks a composite's process: it stays
        time.sleep(60)
        os._exit(0)
    print('held', flush=True)
    time.sleep(60)
''')


def _holder(directory) -> subprocess.Popen:
    process = subprocess.Popen([sys.executable, '-c', HOLD, str(directory)], stdout=subprocess.PIPE, text=True,
                               start_new_session=True)
    assert process.stdout.readline().strip() == 'held'
    return process


def test_a_second_instance_is_refused_until_the_first_one_is_gone_however_it_ended(tmp_path):
    holder = _holder(tmp_path)
    try:
        with pytest.raises(AlreadyRunning, match=rf'app already runs in ROS domain 7 .*\(process {holder.pid}\)'):
            InstanceLock('app', domain=7, directory=tmp_path).acquire()
        InstanceLock('app', domain=8, directory=tmp_path).acquire()  # another domain: another lock
        InstanceLock('other', domain=7, directory=tmp_path).acquire()  # another application
        holder.send_signal(signal.SIGKILL)  # the holder dies without a word; its forked child lives on
        holder.wait()
        lock = InstanceLock('app', domain=7, directory=tmp_path)
        lock.acquire()
        lock.release()
    finally:
        os.killpg(holder.pid, signal.SIGKILL)
        holder.wait()


def test_released_it_can_be_taken_again(tmp_path):
    first = InstanceLock('app', domain=7, directory=tmp_path)
    first.acquire()
    first.release()
    holder = _holder(tmp_path)  # another process takes it: nothing of ours holds it any more
    try:
        with pytest.raises(AlreadyRunning):
            InstanceLock('app', domain=7, directory=tmp_path).acquire()
    finally:
        os.killpg(holder.pid, signal.SIGKILL)
        holder.wait()
