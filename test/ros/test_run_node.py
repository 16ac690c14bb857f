"""run_node, the main() of every node: Ctrl-C at any moment is a stop, a real error is not hidden, and
the stop never runs beside the node's work or its own teardown (no crash at shutdown)."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys

import pytest

pytestmark = pytest.mark.ros

# The factory stands in for a node constructor whose context is shut down under it (a caller of
# rclpy.shutdown): its next call on it (a subscription) fails, and that is a stop.
SCRIPT = '''
import rclpy
from sonar_tracking.ros.runtime import run_node

def factory():
    node = rclpy.create_node('run_node_probe')
    if {interrupt}:
        rclpy.shutdown()
    node.create_subscription(__import__('std_msgs.msg').msg.Empty, 'x', lambda m: None, 1)
    raise ValueError('a real error while building the node')

raise SystemExit(run_node(factory, []))
'''


@pytest.mark.parametrize('interrupt', [True, False])
def test_an_interrupted_start_is_a_clean_stop_and_a_real_error_is_raised(interrupt):
    r = subprocess.run([sys.executable, '-c', SCRIPT.format(interrupt=interrupt)], capture_output=True, text=True,
                       timeout=60)
    if interrupt:
        assert r.returncode == 0 and 'Traceback' not in r.stderr, r.stderr
    else:
        assert r.returncode == 1 and 'ValueError: a real error while building the node' in r.stderr, r.stderr


def test_a_hung_teardown_ends_the_process_with_its_status():
    """exit_if_teardown_hangs: a tool whose work is done leaves even if the teardown blocks (here: forever)."""
    hang = ('import threading\nfrom sonar_tracking.ros.runtime import exit_if_teardown_hangs\n'
            'exit_if_teardown_hangs(3, 0.2)\nthreading.Event().wait()\n')
    r = subprocess.run([sys.executable, '-c', hang], capture_output=True, text=True, timeout=60)
    assert r.returncode == 3 and 'ROS teardown took over 0.2 s' in r.stderr
    done = 'from sonar_tracking.ros.runtime import exit_if_teardown_hangs\nexit_if_teardown_hangs(3, 30.0)\n'
    r = subprocess.run([sys.executable, '-c', done], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stderr == ''     # a teardown that finishes exits as usual


def _signalled(script: str, ready: str, signals) -> tuple[subprocess.Popen, str, str]:
    """Run ``script``; once it prints ``ready`` (and blocks reading stdin), send ``signals``, then let it
    go on; its process, stdout and stderr."""
    proc = subprocess.Popen([sys.executable, '-c', script], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline() == ready
        for signum in signals:
            proc.send_signal(signum)
        out, err = proc.communicate('go\n', timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return proc, out, err


# A callback that blocks until the test has sent the signal, then uses ROS and reports.
CALLBACK = '''
import sys
import rclpy
from std_msgs.msg import Empty
from sonar_tracking.ros.runtime import run_node

def factory():
    node = rclpy.create_node('run_node_callback_probe')
    pub = node.create_publisher(Empty, 'probe', 1)
    def work():
        timer.cancel()
        print('in callback', flush=True)
        sys.stdin.readline()          # returns once the test has sent the signal
        pub.publish(Empty())
        print(f'callback completed, ROS up: {rclpy.ok()}', flush=True)
    timer = node.create_timer(0.01, work)
    return node

raise SystemExit(run_node(factory, []))
'''


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_a_callback_stops_the_node_after_the_callback(signum):
    """The stop waits for the running callback, which finishes with ROS still up; then the node is
    torn down in the same thread and exits 0. (rclpy's own handling cuts the callback short with a
    KeyboardInterrupt and shuts ROS down from a second thread, beside the teardown.)"""
    proc, out, err = _signalled(CALLBACK, 'in callback\n', [signum])
    assert 'callback completed, ROS up: True' in out, err
    assert proc.returncode == 0 and 'Traceback' not in err, err


# Delays every call of rcl_trigger_guard_condition and rcl_shutdown made outside the main thread, as
# a loaded machine delays rclpy's signal thread now and then (its two calls after a signal).
SLOW_SIGNAL_THREAD = r'''
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdlib.h>
#include <sys/syscall.h>
#include <unistd.h>
static void *real(const char *name) {
    void *lib = dlopen("librcl.so", RTLD_NOW | RTLD_NOLOAD);
    void *f = lib ? dlsym(lib, name) : 0;
    return f ? f : dlsym(RTLD_NEXT, name);
}
static void slow(void) {
    if (getpid() != (pid_t)syscall(SYS_gettid)) usleep(20000);
}
int rcl_trigger_guard_condition(void *gc) {
    static int (*f)(void *) = 0;
    if (!f) f = (int (*)(void *))real("rcl_trigger_guard_condition");
    slow();
    return f(gc);
}
int rcl_shutdown(void *context) {
    static int (*f)(void *) = 0;
    if (!f) f = (int (*)(void *))real("rcl_shutdown");
    slow();
    return f(context);
}
'''

BUSY = '''
import rclpy
from std_msgs.msg import Float64
from sonar_tracking.ros.runtime import run_node

def factory():
    node = rclpy.create_node('run_node_busy_probe')
    pub = node.create_publisher(Float64, 'probe', 10)
    count = [0]
    def work():
        x = sum(float(i) for i in range(20000))
        pub.publish(Float64(data=x))
        count[0] += 1
        if count[0] == 3:
            print('working', flush=True)
    node.create_timer(0.0, work)
    return node

raise SystemExit(run_node(factory, []))
'''


def test_a_slow_signal_thread_cannot_crash_the_stop(tmp_path):
    """SIGINT while the node works, with any second thread's part in the stop delayed by 20 ms (a C
    shim preloaded over rcl): the node exits 0 every time. Where rclpy's signal thread does its part
    of the stop beside the main thread's teardown, about two such stops in three end in SIGSEGV or a
    traceback."""
    compiler = shutil.which('cc') or shutil.which('gcc')
    if compiler is None:
        pytest.skip('needs a C compiler for the shim')
    source = tmp_path / 'slow.c'
    source.write_text(SLOW_SIGNAL_THREAD)
    shim = tmp_path / 'libslow.so'
    subprocess.run([compiler, '-shared', '-fPIC', '-O2', '-o', str(shim), str(source), '-ldl'], check=True,
                   capture_output=True, timeout=120)
    env = dict(os.environ, LD_PRELOAD=str(shim), PYTHONFAULTHANDLER='1')
    results = []
    for _ in range(8):
        proc = subprocess.Popen([sys.executable, '-c', BUSY], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, env=env)
        try:
            assert proc.stdout.readline() == 'working\n'
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        results.append((proc.returncode, err[-2000:]))
    assert all(code == 0 and 'Traceback' not in err for code, err in results), results


def test_a_parent_gone_before_the_watch_ends_the_node_at_once():
    """SONAR_TRACKING_PARENT_PID names a process that is not the parent (it ended and the node was
    adopted before it could ask to end with it): the node ends at once with SIGTERM."""
    script = 'from sonar_tracking.ros.runtime import prepare_process\nprepare_process()\nprint("running")\n'
    env = dict(os.environ, SONAR_TRACKING_PARENT_PID=str(os.getpid() + 999_999))
    r = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == -signal.SIGTERM and 'running' not in r.stdout
    env['SONAR_TRACKING_PARENT_PID'] = str(os.getpid())     # the real parent: it runs on
    r = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 0 and 'running' in r.stdout, r.stderr


# A build that is interrupted where third-party code runs a finaliser (as numba's compiler does while
# it warms the kernels up): an exception raised there is swallowed with a traceback.
BUILD = '''
import sys
import rclpy
from sonar_tracking.ros.runtime import run_node

class Finaliser:
    def __del__(self):
        print('building', flush=True)
        sys.stdin.readline()          # returns once the test has sent the signal(s)

def factory():
    node = rclpy.create_node('run_node_build_probe')
    Finaliser()
    print('built', flush=True)
    node.create_timer(0.0, lambda: print('spun', flush=True))
    return node

raise SystemExit(run_node(factory, []))
'''


@pytest.mark.parametrize('signals', [[signal.SIGINT], [signal.SIGINT, signal.SIGTERM]])
def test_a_signal_during_the_build_stops_the_node_once_built_and_a_second_ends_it(signals):
    """One signal while the node is built raises nothing into the build: the build completes, the
    node never spins and exits 0. A second signal ends the process at once with that signal, before
    the build goes on."""
    proc, out, err = _signalled(BUILD, 'building\n', signals)
    if len(signals) == 1:
        assert proc.returncode == 0 and 'Traceback' not in err, err
        assert 'built' in out and 'spun' not in out, out
    else:
        # Sent back to back, the two may reach the handler in either order: the one handled second ends it.
        assert proc.returncode in [-s for s in signals], (proc.returncode, err)
        assert 'built' not in out, out
