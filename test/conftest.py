"""Shared fixtures. DDS traffic of the tests stays on this machine, in a domain of its own."""
from __future__ import annotations

import os

import pytest

# Before any rclpy import: a per-run domain so parallel runs on one machine do not see each other,
# and the package's DDS profile, as every process of the package uses it.
os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
# pytest -n: one domain per worker, moved once (a test's own pytest child inherits the worker's).
_worker = os.environ.get('PYTEST_XDIST_WORKER', '')
if _worker.startswith('gw') and os.environ.get('SONAR_TEST_WORKER') != _worker:
    os.environ['ROS_DOMAIN_ID'] = str((int(os.environ['ROS_DOMAIN_ID']) + int(_worker[2:])) % 100 + 1)
    os.environ['SONAR_TEST_WORKER'] = _worker
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
from sonar_tracking import process  # noqa: E402
from sonar_tracking.ros.runtime import configure_dds  # noqa: E402 (must precede rclpy)

configure_dds()
process.drop_stale_kernel_caches()   # as every process of the package does where it starts


@pytest.fixture(scope='session')
def rosbags_types():
    """Message builder on the rosbags ROS 2 Jazzy typestore (dataclasses with numpy arrays)."""
    from rosbags.typesys import Stores, get_typestore

    from sonar_tracking.msgs import RosbagsTypes
    return RosbagsTypes(get_typestore(Stores.ROS2_JAZZY))


@pytest.fixture(params=['rclpy', 'rosbags'])
def types(request, rosbags_types):
    """Both message representations: every adapter must work on each."""
    from sonar_tracking.msgs import rclpy_types
    return rclpy_types() if request.param == 'rclpy' else rosbags_types


def spin(executor) -> None:
    """``executor.spin()`` in a test's background thread, kept alive when the test's thread destroys a
    subscription or client while the executor waits on it: rclpy then raises ``InvalidHandle`` in the
    executor's thread, which would end it and silently stop every callback of the test."""
    from rclpy.exceptions import InvalidHandle
    while True:
        try:
            executor.spin()
            return          # shut down
        except InvalidHandle:
            continue        # an entity went away under the wait set: wait on the others


@pytest.fixture(scope='session')
def graph_node():
    """An rclpy node of the test process, for looking at the ROS graph."""
    import rclpy
    from rclpy.context import Context
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node('sonar_tracking_test_probe', context=context)
    yield node
    node.destroy_node()
    rclpy.shutdown(context=context)


@pytest.fixture
def ros(graph_node):
    """The probe node spun by a background executor, plus helpers to wait on futures and conditions."""
    import threading
    import time

    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=graph_node.context)
    executor.add_node(graph_node)
    thread = threading.Thread(target=spin, args=(executor,), daemon=True)
    thread.start()

    class Ros:
        node = graph_node

        @staticmethod
        def wait(predicate, timeout=20.0, what='condition'):
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                if predicate():
                    return
                time.sleep(0.02)
            raise AssertionError(f'timed out after {timeout} s waiting for {what}')

        @staticmethod
        def wait_listened(outputs, timeout=30.0):
            """Wait until each ``(diagnostic status name, topic)`` in ``outputs`` reports a matched reader
            (``subscribers TOPIC`` >= 1 in the node's /diagnostics): its messages will now be delivered."""
            from diagnostic_msgs.msg import DiagnosticArray
            heard: dict = {}

            def on_diag(msg):
                for st in msg.status:
                    heard.update({(st.name, kv.key): kv.value for kv in st.values})
            sub = graph_node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 50)
            try:
                Ros.wait(lambda: all(int(heard.get((name, f'subscribers {topic}'), 0)) >= 1 for name, topic in outputs),
                         timeout, f'matched readers of {outputs}')
            finally:
                graph_node.destroy_subscription(sub)

        @staticmethod
        def call(client, request, timeout=20.0, resend=2.0):
            """The response to ``request``, sent again every ``resend`` seconds until one comes:
            Fast DDS drops a response when the server has not yet matched the client's reader
            (ros2/rmw_fastrtps#390, #467), so a first call right after wait_for_service can go
            unanswered. Only for idempotent requests (parameters, enable); give others
            ``resend=timeout``."""
            deadline = time.monotonic() + timeout
            while True:
                future = client.call_async(request)
                try:
                    Ros.wait(future.done, min(resend, max(deadline - time.monotonic(), 0.0)), 'a service response')
                    return future.result()
                except AssertionError:
                    client.remove_pending_request(future)
                    if time.monotonic() >= deadline:
                        raise AssertionError(f'timed out after {timeout} s waiting for a service response') from None

    yield Ros
    executor.shutdown(timeout_sec=2.0)
    executor.remove_node(graph_node)
    thread.join(timeout=5.0)
    for sub in list(graph_node.subscriptions):
        graph_node.destroy_subscription(sub)
    for client in list(graph_node.clients):
        graph_node.destroy_client(client)


def child_process(cmd: list[str], **kwargs):
    """``subprocess.Popen(cmd, **kwargs)`` in a session of its own that ends with this test process,
    however that ends (a CI timeout's SIGKILL included): the child gets SIGTERM then
    (:func:`sonar_tracking.process.child_dies_with_parent`)."""
    import subprocess
    return subprocess.Popen(cmd, start_new_session=True, preexec_fn=process.child_dies_with_parent(), **kwargs)


@pytest.fixture
def launch():
    """Start package nodes as child processes (``python -m sonar_tracking.nodes.NAME``) that end with
    the test process (:func:`child_process`); ``launch.stop(proc)`` interrupts one and returns its
    log; all are stopped at teardown."""
    import signal
    import subprocess
    import sys

    procs = []

    def start(module: str, *params: str, params_file: str | None = None) -> subprocess.Popen:
        cmd = [sys.executable, '-m', f'sonar_tracking.nodes.{module}', '--ros-args']
        if params_file:
            cmd += ['--params-file', str(params_file)]
        for p in params:
            cmd += ['-p', p]
        proc = child_process(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(proc)
        return proc

    def stop(proc: subprocess.Popen, timeout: float = 15.0) -> str:
        """SIGINT the node's process group, SIGKILL if it has not ended after ``timeout``; its stderr."""
        os.killpg(proc.pid, signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            _, err = proc.communicate()
        return err

    start.stop = stop
    yield start
    for proc in procs:
        if proc.poll() is None:
            stop(proc, 10.0)


@pytest.fixture
def inproc(graph_node):
    """``inproc(NodeClass, **params)``: a package node in this process (the probe's context), spun by an
    executor thread; destroyed at teardown. Faster than a process and shares the probe's DDS participant."""
    import threading

    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    started = []

    def start(node_cls, **params):
        node = node_cls(context=graph_node.context,
                        parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        executor = SingleThreadedExecutor(context=graph_node.context)
        executor.add_node(node)
        thread = threading.Thread(target=spin, args=(executor,), daemon=True)
        thread.start()
        started.append((node, executor, thread))
        return node

    yield start
    for node, executor, thread in started:
        executor.shutdown(timeout_sec=2.0)
        thread.join(timeout=5.0)
        node.destroy_node()
