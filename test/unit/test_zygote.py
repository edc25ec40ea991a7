"""The zygote (itasc_core.composition.zygote): composite processes forked from a copy of the process
made before ROS starts, which the asking process then owns as its children, with the command line
of a started composite process and its exit code as subprocess.Popen reports it.

Each case runs in a process of its own: making a zygote turns the maker into a child subreaper and
needs a process without other threads, which the test process is not.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time

SCRIPT = textwrap.dedent('''
    import json, os, sys, time
    from itasc_core.composition.zygote import HOST_COMMAND, Zygote

    zygote = Zygote.make()
    assert zygote is not None
    bogus = zygote.start(['--no-such-option'])
    # a composite process that waits: opening its spec, a FIFO, blocks until a writer opens it
    fifo = os.path.join(sys.argv[1], 'spec.json')
    os.mkfifo(fifo)
    argv = ['--spec', fifo, '--namespace', '/x', '--parent-namespace', '/', '--parent-pid', str(os.getpid())]
    waiting = zygote.start(argv)
    with open(f'/proc/{waiting.pid}/cmdline', 'rb') as cmdline:
        title = cmdline.read().replace(b'\\0', b' ').decode().strip()
    with open(f'/proc/{waiting.pid}/stat', 'rb') as stat:
        parent = int(stat.read().rsplit(b')', 1)[1].split()[1])
    open(fifo, 'w').close()  # an empty spec: not JSON
    codes = [bogus.wait(timeout=30), waiting.wait(timeout=30)]
    print(json.dumps({'codes': codes, 'title': title, 'parent': parent, 'me': os.getpid(),
                      'zygote': zygote.pid, 'expected': ' '.join([*HOST_COMMAND, *argv])}))
''')


def test_a_forked_composite_process_is_the_askers_child_and_reports_how_it_ended(tmp_path):
    done = subprocess.run([sys.executable, '-c', SCRIPT, str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    facts = json.loads(done.stdout)
    # argparse refuses the option (exit 2); a spec that is not JSON is a traceback and exit 1
    assert facts['codes'] == [2, 1], done.stderr
    assert 'usage: host.py' in done.stderr and 'host.py: error:' in done.stderr
    assert 'JSONDecodeError' in done.stderr
    # re-parented to the process that asked for it, which could wait for it
    assert facts['parent'] == facts['me'] != facts['zygote']
    # ps shows what a started composite process shows, from its first instant
    assert facts['title'] == facts['expected']


def test_the_zygote_ends_with_the_process_that_made_it():
    script = SCRIPT.split('bogus =')[0] + 'print(zygote.pid, flush=True)\n'
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    zygote = int(done.stdout)
    deadline = time.monotonic() + 10
    while _alive(zygote) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(zygote)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f'/proc/{pid}/stat', 'rb') as stat:  # a zombie is dead, waiting for its parent
        return stat.read().rsplit(b')', 1)[1].split()[0] != b'Z'


def test_a_composite_process_still_starts_once_the_zygote_is_gone():
    script = SCRIPT.split('bogus =')[0] + textwrap.dedent('''
        import signal
        os.kill(zygote.pid, signal.SIGKILL)
        os.waitpid(zygote.pid, 0)
        first, second = zygote.start(['--no-such-option']), zygote.start(['--no-such-option'])
        print(json.dumps({'codes': [first.wait(timeout=60), second.wait(timeout=60)], 'gone': zygote.gone}))
    ''')
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    # started as new interpreters: argparse of the host refuses the option, as in a forked one
    assert json.loads(done.stdout) == {'codes': [2, 2], 'gone': True}
    assert 'is gone' in done.stderr and done.stderr.count('usage: host.py') == 2


def test_a_composite_process_runs_on_while_its_parent_lives_whoever_its_direct_parent_is(tmp_path, context):
    """A composite process forked by a zygote is the child of the zygote's intermediate process
    until that one has exited, which on a loaded machine came after the composite's bring-up: the
    composite took the intermediate process's pid for a sign that its parent was gone and ended
    (the per-composite Ctrl-C test of test_bootstrap, in about half of the clean-clone runs: 'hold'
    never configured). Here the composite's direct parent is a process in between for good; the
    process named by --parent-pid lives on. It ends, not in order (exit 1), once that one is gone."""
    import rclpy
    from processes import Spawned

    from itasc_bringup.apps import load_composition
    from itasc_core.composition.model import walk
    from itasc_core.composition.zygote import HOST_COMMAND

    hold = next(m for _, m in walk(load_composition('pattern_demo')) if m.name == 'hold')
    spec = tmp_path / 'hold.json'
    spec.write_text(json.dumps(hold.model_dump(by_alias=True, exclude_defaults=True)))
    parent = subprocess.Popen(['sleep', '600'])
    between = 'import subprocess, sys\nsys.exit(subprocess.call(sys.argv[1:]))\n'
    node = rclpy.create_node('probe', context=context)
    try:
        with Spawned([sys.executable, '-c', between, *HOST_COMMAND, '--spec', str(spec), '--namespace',
                      '/zygote_test/hold', '--parent-namespace', '/zygote_test',
                      '--parent-pid', str(parent.pid)]) as host:
            deadline = time.monotonic() + 60
            while ('coordinator', '/zygote_test/hold') not in node.get_node_names_and_namespaces():
                assert host.process.poll() is None, host.output()
                assert time.monotonic() < deadline, 'the composite never came up\n' + host.output()
                time.sleep(0.1)
            time.sleep(1.0)  # 20 turns of the composite's loop, each of which looks for its parent
            assert host.process.poll() is None, host.output()
            parent.kill()
            parent.wait()
            assert host.finish(timeout=30) == 1, host.output()
        assert f'parent process {parent.pid} is gone' in host.err
    finally:
        parent.kill()
        parent.wait()
        node.destroy_node()
