"""Where ``sonar_view`` is served: the ports (the defaults, or free ones when those are taken), the
address both servers listen on (127.0.0.1 unless asked otherwise), and the web viewer.

The recording server is the Rerun SDK's (``GrpcServerSink``, which takes a bind address). The
SDK's own web server (``rerun.serve_web_viewer``) takes none and listens on every interface
(0.0.0.0), so the web viewer is served instead by Rerun's command-line program from the same
wheel, ``rerun --serve-web --bind ADDR``, as a child process that dies with the view
(:class:`WebViewer`). Neither server reports a port that is taken (the SDK's fails silently), so
:func:`listening` reads from ``/proc`` which addresses a process really listens on. Standard
library only.
"""
from __future__ import annotations

import os
import queue
import re
import socket
import subprocess
import sys
import threading
import time
from collections import deque
from pathlib import Path
from urllib.parse import quote

from sonar_tracking import process

__all__ = ['DEFAULT_GRPC_PORT', 'DEFAULT_WEB_PORT', 'LOOPBACK', 'ServeError', 'listening', 'port_free',
           'pick_port', 'url_host', 'grpc_uri', 'viewer_url', 'viewer_connected', 'viewer_binary', 'WebViewer']

DEFAULT_GRPC_PORT = 9876
DEFAULT_WEB_PORT = 9090
LOOPBACK = '127.0.0.1'


class ServeError(RuntimeError):
    """A server could not start; the message says where and why."""


def _address(hex_addr: str) -> str:
    """``/proc/net/tcp*`` address (hex, 32-bit words in host order) -> text."""
    raw = bytes.fromhex(hex_addr)
    words = b''.join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4)) if sys.byteorder == 'little' else raw
    return socket.inet_ntop(socket.AF_INET if len(raw) == 4 else socket.AF_INET6, words)


def _sockets(state: str) -> list[tuple[str, int, int, str]]:
    """``(local address, local port, socket inode, table)`` of every TCP socket in ``state`` (hex)."""
    out = []
    for table in ('/proc/net/tcp', '/proc/net/tcp6'):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) > 9 and fields[3] == state:
                addr, port = fields[1].rsplit(':', 1)
                out.append((_address(addr), int(port, 16), int(fields[9]), table))
    return out


def listening(pid: int | None = None) -> set[tuple[str, int]]:
    """``(address, port)`` pairs a process (default: this one) listens on by TCP, from ``/proc`` (Linux)."""
    fd_dir = Path(f'/proc/{pid or os.getpid()}/fd')
    inodes = set()
    try:
        for fd in fd_dir.iterdir():
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            if target.startswith('socket:['):
                inodes.add(int(target[8:-1]))
    except OSError:
        return set()
    return {(addr, port) for addr, port, inode, _ in _sockets('0A') if inode in inodes}


def port_free(host: str, port: int) -> bool:
    """Whether a server could listen on ``host:port`` now (as the servers do, with SO_REUSEADDR)."""
    family = socket.AF_INET6 if ':' in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def pick_port(host: str, default: int, avoid: set[int] | None = None) -> int:
    """``default`` if it is free on ``host``, else a free port the system chooses."""
    avoid = avoid or set()
    if default not in avoid and port_free(host, default):
        return default
    family = socket.AF_INET6 if ':' in host else socket.AF_INET
    for _ in range(20):
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.bind((host, 0))
            port = s.getsockname()[1]
        if port not in avoid:
            return port
    raise ServeError(f'no free port on {host}')


def url_host(bind: str) -> str:
    """The host name a browser uses for servers listening on ``bind`` (every interface: this machine's name)."""
    host = socket.gethostname() if bind in ('0.0.0.0', '::', '') else bind
    return f'[{host}]' if ':' in host else host


def grpc_uri(bind: str, port: int) -> str:
    """The recording server's address for a viewer."""
    return f'rerun+http://{url_host(bind)}:{port}/proxy'


def viewer_url(bind: str, web_port: int, grpc: str) -> str:
    """The web viewer's address, told which recording server to stream from."""
    return f'http://{url_host(bind)}:{web_port}/?url={quote(grpc, safe="")}'


def viewer_connected(port: int) -> bool:
    """Whether a TCP connection to local ``port`` is established (a viewer streaming from the server).

    Reads ``/proc/net/tcp`` and ``tcp6`` (Linux); elsewhere it answers True, so the view logs always.
    """
    if not any(Path(t).exists() for t in ('/proc/net/tcp', '/proc/net/tcp6')):
        return True
    return any(p == port for _, p, _, _ in _sockets('01'))


def viewer_binary() -> Path:
    """Rerun's command-line program from the ``rerun-sdk`` wheel (``RERUN_CLI_PATH`` overrides it)."""
    if os.environ.get('RERUN_CLI_PATH'):
        return Path(os.environ['RERUN_CLI_PATH'])
    import rerun_cli
    base = Path(rerun_cli.__file__).parent
    bundled = base / 'Rerun.app' / 'Contents' / 'MacOS' / 'Rerun'
    return bundled if bundled.exists() else base / ('rerun.exe' if sys.platform.startswith('win') else 'rerun')


_HOSTING = re.compile(r'Hosting a web-viewer at http://\S+?:(\d+)')


class WebViewer:
    """Rerun's web viewer served over HTTP on ``bind:port`` by a child process (``rerun --serve-web
    --bind``), pointed at the recording server ``grpc``; :meth:`stop` ends it, and it gets SIGTERM
    if this process dies first."""

    def __init__(self, bind: str, port: int, grpc: str, timeout: float = 30.0) -> None:
        exe = viewer_binary()
        if not exe.exists():
            raise ServeError(f"Rerun's viewer program is missing ({exe}): reinstall the view extra (`make view`)")
        self.port = port
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.output: deque[str] = deque(maxlen=50)
        self._starting = True
        self.proc = subprocess.Popen(
            [str(exe), '--serve-web', '--bind', bind, '--web-viewer-port', str(port), grpc],
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            start_new_session=True, preexec_fn=process.child_dies_with_parent(), env=dict(os.environ, NO_COLOR='1'))
        threading.Thread(target=self._read, daemon=True).start()
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                self.stop()
                raise ServeError(f'the web viewer did not start on {bind}:{port} within {timeout:g} s') from None
            if line is None:
                self.proc.wait()
                text = ' | '.join(x.strip() for x in list(self.output)[-5:] if x.strip())
                raise ServeError(f'the web viewer could not serve on {bind}:{port} (exit status '
                                 f'{self.proc.returncode}): {text}')
            m = _HOSTING.search(line)
            if m:
                self.port, self._starting = int(m.group(1)), False
                return

    def _read(self) -> None:
        # Drains the child's output for as long as it runs (a full pipe would stop it); only the
        # start-up lines are looked at, the last few kept for error messages.
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.output.append(line)
            if self._starting:
                self.lines.put(line)
        self.lines.put(None)

    def running(self) -> bool:
        return self.proc.poll() is None

    def stop(self) -> None:
        """End the child (SIGTERM, then SIGKILL after 5 s)."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
