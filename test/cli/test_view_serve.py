"""sonar_view's servers: free ports when the defaults are taken, an error for a port asked for that is
taken, and both servers (the recording's and the web viewer's) reachable on 127.0.0.1 only unless
``--bind`` says otherwise."""
from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from urllib.parse import parse_qs, urlparse

import pytest

from sonar_tracking import process
from sonar_tracking.cli.view.serve import listening, pick_port, port_free, url_host

pytest.importorskip('rerun')  # the view extra (`make view-deps` installs it)


def children(pid: int) -> list[int]:
    """The process and its descendants (Linux ``/proc/PID/task/*/children``)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        for task in Path(f'/proc/{p}/task').glob('*'):
            try:
                todo += [int(c) for c in (task / 'children').read_text().split()]
            except OSError:
                pass
    return out


def start_view(args: list[str], log: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.sonar_view', *args], stdout=log.open('w'),
                            stderr=subprocess.STDOUT, start_new_session=True,
                            preexec_fn=process.child_dies_with_parent())


def wait_url(proc: subprocess.Popen, log: Path, timeout: float = 60.0) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        m = re.search(r'^view: (\S+)', log.read_text(), re.M)
        if m:
            return m.group(1)
        if proc.poll() is not None:
            break
        time.sleep(0.05)
    raise AssertionError(f'no view address:\n{log.read_text()[-2000:]}')


def stop(proc: subprocess.Popen) -> int:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(30)
    return proc.returncode


def other_address() -> str | None:
    """An address of this machine that is not loopback, if it has one."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(('192.0.2.1', 9))  # no packet is sent: this only picks the outgoing interface
            addr = s.getsockname()[0]
        except OSError:
            return None
    return None if addr.startswith('127.') else addr


def scene_tests():
    """test_sonar_view.py as a module (its scan messages and bag writer)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location('view_scene_tests', Path(__file__).with_name('test_sonar_view.py'))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope='module')
def bag(tmp_path_factory, rosbags_types):
    path = tmp_path_factory.mktemp('serve') / 'bag'
    scene_tests().write_bag(path, rosbags_types, 2)
    return path


def test_two_views_at_once_are_served_on_their_own_ports_on_127_0_0_1_only(tmp_path, bag):
    views = [start_view(['--bag', str(bag)], tmp_path / f'view{i}.log') for i in range(2)]
    try:
        urls = [wait_url(v, tmp_path / f'view{i}.log') for i, v in enumerate(views)]
        ports = []
        for url, view in zip(urls, views):
            u = urlparse(url)
            grpc = urlparse(parse_qs(u.query)['url'][0])
            assert u.hostname == '127.0.0.1' and grpc.hostname == '127.0.0.1', url
            ports += [u.port, grpc.port]
            # Every socket the view and its web viewer listen on is on 127.0.0.1, and serves what it says.
            sockets = {s for pid in children(view.pid) for s in listening(pid)}
            assert {(('127.0.0.1', u.port)), ('127.0.0.1', grpc.port)} <= sockets, sockets
            assert {addr for addr, _ in sockets} == {'127.0.0.1'}, sockets
            with urllib.request.urlopen(url, timeout=30) as page:
                assert page.status == 200 and b'Rerun' in page.read()
        assert len(set(ports)) == 4, ports  # the second view found free ports
        addr = other_address()
        for port in ports if addr else ():
            with socket.socket() as s, pytest.raises(OSError):
                s.settimeout(5)
                s.connect((addr, port))
    finally:
        codes = [stop(v) for v in views]
    assert codes == [0, 0], [(tmp_path / f'view{i}.log').read_text()[-1000:] for i in range(2)]
    # The web viewers went with their views.
    assert not any(p == port for port in ports for _, p in listening_anywhere())


def listening_anywhere() -> set[tuple[str, int]]:
    from sonar_tracking.cli.view.serve import _sockets
    return {(addr, port) for addr, port, _, _ in _sockets('0A')}


@pytest.mark.parametrize('option', ['--web-port', '--grpc-port'])
def test_a_port_asked_for_that_is_taken_is_an_error(tmp_path, bag, option):
    with socket.socket() as taken:
        taken.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        r = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.sonar_view', '--bag', str(bag), option,
                            str(port)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and f'127.0.0.1:{port}' in r.stderr, r.stderr


def test_bind_must_be_an_address_and_a_default_port_taken_is_replaced():
    r = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.sonar_view', '--bind', 'localhost'],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and '--bind localhost' in r.stderr
    with socket.socket() as taken:
        taken.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert not port_free('127.0.0.1', port)
        other = pick_port('127.0.0.1', port)
        assert other != port and port_free('127.0.0.1', other)
        assert (('127.0.0.1', port)) in listening()
    assert url_host('127.0.0.1') == '127.0.0.1' and url_host('::1') == '[::1]'
    assert url_host('0.0.0.0') == socket.gethostname()
