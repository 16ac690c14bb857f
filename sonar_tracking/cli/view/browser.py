"""Headless Chromium looking at ``sonar_view``, for the view's tests and benchmarks.

:class:`Chromium` drives Debian's ``chromium`` over the DevTools protocol on a pipe
(``--remote-debugging-pipe``, no port) with software WebGL (SwiftShader), as a machine without GPU
renders. The Rerun web viewer's page keeps its viewer as ``window._handle``; :meth:`Chromium.recording`
and :meth:`Chromium.layout` fetch what the page holds (the recording as ``.rrd`` bytes, the active
blueprint), so a test reads what reached the browser, not what was sent. :func:`rrd_columns`,
:func:`panel_names` and :func:`latest_log_time` read such bytes (they need the view extra). Standard
library only at import.
"""
from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from sonar_tracking import process

__all__ = ['find_chromium', 'Chromium', 'rrd_columns', 'panel_names', 'log_times', 'latest_log_time', 'page_lags',
           'timeline_range']

_BYTES_JS = '''(() => {{ const h = window._handle; if (!h) return null;
  let a; try {{ a = h.{method}(); }} catch (e) {{ return {{error: String(e)}}; }}
  let s = ''; for (let i = 0; i < a.length; i += 32768) s += String.fromCharCode.apply(null, a.subarray(i, i + 32768));
  return {{data: btoa(s)}}; }})()'''


def find_chromium() -> str | None:
    """The path of a Chromium-family browser on this machine, or None."""
    for name in ('chromium', 'chromium-browser', 'google-chrome'):
        path = shutil.which(name)
        if path:
            return path
    return None


class Chromium:
    """Headless Chromium driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``), its
    page ``width`` x ``height`` pixels; ``network``: record the page's network events (:meth:`received_bytes`)."""

    def __init__(self, width: int = 1600, height: int = 1000, network: bool = False) -> None:
        exe = find_chromium()
        if exe is None:
            raise FileNotFoundError("no chromium on this machine (Debian's: apt-get install chromium)")
        to_child, self._w = os.pipe()
        self._r, from_child = os.pipe()
        self.profile = tempfile.mkdtemp(prefix='sonar_view_chromium_')
        args = [exe, '--headless=new', '--remote-debugging-pipe', '--no-sandbox',
                '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--no-first-run',
                '--disable-background-networking', f'--user-data-dir={self.profile}',
                f'--window-size={width},{height}', 'about:blank']

        def fds() -> None:
            os.dup2(to_child, 3)
            os.dup2(from_child, 4)
        self.proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=process.child_dies_with_parent(then=fds),
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        os.close(to_child)
        os.close(from_child)
        self._id, self._buf, self.events = 0, b'', []
        target = self.call('Target.createTarget', url='about:blank')['targetId']
        self.session = self.call('Target.attachToTarget', targetId=target, flatten=True)['sessionId']
        self.size = (width, height)
        self.page('Page.enable')
        if network:  # network events for received_bytes (DevTools then sees every streamed chunk)
            self.page('Network.enable')
        self.page('Emulation.setDeviceMetricsOverride', width=width, height=height, deviceScaleFactor=1, mobile=False)

    def call(self, method: str, session: str | None = None, **params) -> dict:
        self._id += 1
        msg = {'id': self._id, 'method': method, 'params': params}
        if session:
            msg['sessionId'] = session
        os.write(self._w, json.dumps(msg).encode() + b'\0')
        while True:
            while b'\0' not in self._buf:
                chunk = os.read(self._r, 1 << 20)
                if not chunk:
                    raise RuntimeError('chromium closed the DevTools pipe')
                self._buf += chunk
            raw, self._buf = self._buf.split(b'\0', 1)
            reply = json.loads(raw)
            if reply.get('id') == self._id:
                if 'error' in reply:
                    raise RuntimeError(f'{method}: {reply["error"]}')
                return reply['result']
            if reply.get('method', '').startswith('Network.'):  # kept for received_bytes
                self.events.append(reply)

    def page(self, method: str, **params) -> dict:
        return self.call(method, self.session, **params)

    def open(self, url: str) -> None:
        """Load ``url`` in the page (forgetting the network events of the previous one)."""
        self.events.clear()
        self.page('Page.navigate', url=url)

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (promises awaited)."""
        reply = self.page('Runtime.evaluate', expression=expression, returnByValue=True, awaitPromise=True)
        if 'exceptionDetails' in reply:
            raise RuntimeError(f'{expression[:60]}...: {reply["exceptionDetails"].get("text")}')
        return reply['result'].get('value')

    def viewer_started(self) -> bool:
        """Whether the page's Rerun viewer is up (``window._handle`` exists)."""
        return bool(self.evaluate('!!window._handle'))

    def _bytes(self, method: str) -> bytes | None:
        got = self.evaluate(_BYTES_JS.format(method=method))
        if not got or 'data' not in got:
            return None  # no viewer yet, or no recording received yet
        return base64.b64decode(got['data'])

    def recording(self) -> bytes | None:
        """The recording the page's viewer holds, as ``.rrd`` bytes (None before it has one)."""
        return self._bytes('save_recording')

    def viewer_state(self) -> bytes | None:
        """The page viewer's state (Rerun's Viewer Control ``GetStateResponse``, protobuf bytes), computed
        at once and small: the active recording's timelines and their ranges, the panels; None before
        the viewer runs."""
        return self._bytes('viewer_state')

    def newest_log_time(self) -> float | None:
        """The newest ``log_time`` (when the view logged it, seconds of the epoch) of the rows the page
        holds, read from :meth:`viewer_state` (the page does not serialize its recording for it, as
        :meth:`recording` does); None before it holds a row."""
        state = self.viewer_state()
        return None if state is None else timeline_range(state, 'log_time')[1]

    def layout(self) -> bytes | None:
        """The page's active blueprint, as ``.rrd`` bytes (None before it has one)."""
        return self._bytes('save_blueprint')

    def screenshot(self) -> bytes:
        return base64.b64decode(self.page('Page.captureScreenshot', format='png')['data'])

    def received_bytes(self, url_part: str) -> int:
        """Bytes the page received on requests whose URL contains ``url_part`` (DevTools Network events)."""
        ids = {e['params']['requestId'] for e in self.events
               if e.get('method') == 'Network.requestWillBeSent' and url_part in e['params']['request']['url']}
        return sum(e['params']['dataLength'] for e in self.events
                   if e.get('method') == 'Network.dataReceived' and e['params']['requestId'] in ids)

    def close(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._w)
        os.close(self._r)
        shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _path(rrd: Path | bytes, tmp: list) -> Path:
    if isinstance(rrd, (bytes, bytearray)):
        with tempfile.NamedTemporaryFile(suffix='.rrd', delete=False) as f:
            f.write(rrd)
        tmp.append(f.name)
        return Path(f.name)
    return Path(rrd)


def rrd_columns(rrd: Path | bytes, timeline: str = 'time') -> dict[str, dict[str, list]]:
    """entity -> component column -> ``[(time_ns, value), ...]`` in time order, from an ``.rrd`` file
    or its bytes (``time_ns``: the ``timeline`` value, None for static rows)."""
    import pyarrow as pa
    from rerun.chunk import RrdReader
    tmp: list[str] = []
    out: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    try:
        reader = RrdReader(_path(rrd, tmp))
        for chunk in reader.stream():
            batch = chunk.to_record_batch()
            names = batch.schema.names
            stamps = (batch.column(timeline).cast(pa.int64()).to_pylist() if timeline in names
                      else [None] * batch.num_rows)
            for name in names:
                if name in ('rerun.controls.RowId', 'log_time', timeline):
                    continue
                out[chunk.entity_path][name].extend(zip(stamps, batch.column(name).to_pylist()))
    finally:
        for name in tmp:
            os.unlink(name)
    for cols in out.values():
        for rows in cols.values():
            rows.sort(key=lambda r: -1 << 62 if r[0] is None else r[0])
    return out


def _protobuf_fields(data: bytes):
    """(field number, value) of a protobuf message's fields: integers for varint and fixed fields,
    bytes for length-delimited ones (a nested message, a string or packed values)."""
    i = 0

    def varint() -> int:
        nonlocal i
        value = shift = 0
        while True:
            byte = data[i]
            i += 1
            value |= (byte & 0x7F) << shift
            shift += 7
            if byte < 0x80:
                return value
    while i < len(data):
        key = varint()
        field, wire = key >> 3, key & 7
        if wire == 0:
            yield field, varint()
        elif wire in (1, 5):
            n = 8 if wire == 1 else 4
            yield field, int.from_bytes(data[i:i + n], 'little')
            i += n
        elif wire == 2:
            n = varint()
            yield field, data[i:i + n]
            i += n
        else:
            raise ValueError(f'protobuf wire type {wire} not read here')


def timeline_range(state: bytes, timeline: str) -> tuple[float | None, float | None]:
    """The range of ``timeline`` in the active recording of a viewer state (:meth:`Chromium.viewer_state`),
    in seconds (nanosecond timelines), or (None, None) without rows on it. In Rerun 0.41's
    ``GetStateResponse`` field 3 is the active recording, its repeated field 2 a timeline: 1 its name
    (``{1: name}``), 3 its range (``{1: min, 2: max}``)."""
    def message(b: bytes) -> dict[int, list]:
        out: dict[int, list] = defaultdict(list)
        for field, value in _protobuf_fields(b):
            out[field].append(value)
        return out
    for recording in message(state).get(3, []):
        for entry in message(recording).get(2, []):
            fields = message(entry)
            names = [message(n).get(1, [b''])[0] for n in fields.get(1, [])]
            if names == [timeline.encode()] and fields.get(3):
                span = message(fields[3][0])
                lo, hi = span.get(1, [None])[0], span.get(2, [None])[0]
                return (None if lo is None else lo * 1e-9, None if hi is None else hi * 1e-9)
    return None, None


def log_times(rrd: Path | bytes) -> list[float]:
    """The ``log_time`` of every row of a recording (when the view logged it, seconds of the epoch),
    ascending."""
    import pyarrow as pa
    from rerun.chunk import RrdReader
    tmp: list[str] = []
    times: list[int] = []
    try:
        for chunk in RrdReader(_path(rrd, tmp)).stream():
            batch = chunk.to_record_batch()
            if 'log_time' in batch.schema.names and batch.num_rows:
                times += batch.column('log_time').cast(pa.int64()).to_pylist()
    finally:
        for name in tmp:
            os.unlink(name)
    return sorted(t * 1e-9 for t in times if t is not None)


def latest_log_time(rrd: Path | bytes) -> float | None:
    """The latest ``log_time`` (when the view logged it, seconds of the epoch) of a recording's rows."""
    times = log_times(rrd)
    return times[-1] if times else None


def page_lags(polls: list[tuple[float, float | None]], logged: list[float]) -> list[float]:
    """How stale the page was at each poll ``(when, newest log_time the page held)``, given the
    ascending ``log_time`` of every row the view logged: the age of the oldest row logged by then
    that the page did not hold yet, 0 when it held all [s]. (The wall clock minus the newest row
    would count the time since the view last logged anything, which a quiet sensor makes long.)"""
    import bisect
    out = []
    for when, newest in polls:
        i = 0 if newest is None else bisect.bisect_right(logged, newest)
        out.append(when - logged[i] if i < len(logged) and logged[i] <= when else 0.0)
    return out


def panel_names(rrd: Path | bytes) -> list[str]:
    """The panel (view) names of the last blueprint in an ``.rrd`` file or bytes."""
    import pyarrow as pa
    from rerun.chunk import RrdReader
    tmp: list[str] = []
    try:
        reader = RrdReader(_path(rrd, tmp))
        best: tuple[int, list[str]] = (-1, [])
        for store in reader.blueprints():
            names, last = [], -1
            for chunk in reader.stream(store=store):
                batch = chunk.to_record_batch()
                if 'ViewBlueprint:display_name' in batch.schema.names:
                    names += [v[0] for v in batch.column('ViewBlueprint:display_name').to_pylist() if v]
                if 'log_time' in batch.schema.names and batch.num_rows:
                    last = max(last, max(batch.column('log_time').cast(pa.int64()).to_pylist()))
            if last >= best[0]:
                best = (last, names)
        return best[1]
    finally:
        for name in tmp:
            os.unlink(name)


def wait_until(predicate, timeout: float, what: str, poll: float = 0.25):
    """Poll ``predicate`` until it returns something true (returned) or ``timeout`` passes (TimeoutError)."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise TimeoutError(f'waited {timeout:g} s for {what}')
        time.sleep(poll)
