"""Ping Viewer ``.bin`` logs of a Ping360, as the logger writes them.

The file is big-endian Qt ``QDataStream`` data: a header (the string ``PingViewer sensor log file``,
an int32 version, five strings of build information, int32 sensor family and type), then records
of a time-of-day string and a chunk of the bytes that came from the sensor, each an uint32 size +
bytes (strings in UTF-16). The chunks are what the serial port or socket delivered: one ping
message may be split over several records and one record may hold several messages, so the
records' bytes are joined into one ping-protocol stream (``'BR'``, uint16 payload length, uint16
message id, two device ids, payload, uint16 sum of the bytes before it) and cut into messages
there. Bytes outside a message with a valid checksum are skipped and counted.

A message takes the time of the record holding its first byte. Times are ``hh:mm:ss.zzz`` in the
recording machine's digits (any Unicode decimal digits: Extended Arabic-Indic, Devanagari, ...),
without a date: the date comes from ``date`` (``YYYY-MM-DD``), else from the first ``YYYYMMDD``
in the file name, else 1970-01-01 (UTC); a time that goes back by more than 12 h is the next day.
A record whose time cannot be read takes the time of the record before it (the first readable
one for leading records). When no record time can be read, pings are stamped in order from the
start of the day at their sample timing (transmit duration + samples x sample period), and a
warning says so.

Pings of ``device_data`` (2300) and ``auto_device_data`` (2301) carry their own sample period and
count; pings whose settings differ never share a sector (:attr:`~.sweeps.Ping.settings`), so a
log whose range was changed part-way keeps the two settings apart. Angles are gradians.
"""
from __future__ import annotations

import re
import struct
import unicodedata
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from sonar_tracking.io.importers.conventions import PING360, Sensor
from sonar_tracking.io.importers.options import ImportOptions
from sonar_tracking.io.importers.recording import (
    Item,
    Recording,
    RecordingError,
    TopicInfo,
    bins_geometry,
    head_bearing,
)
from sonar_tracking.io.importers.sweeps import Ping

__all__ = ['PingViewerRecording', 'time_of_day_ns', 'PingStream', 'PING_MESSAGES']

DAY_NS = 86400 * 10**9
TICK = 25e-9                    # s: the Ping360's sample period unit
#: Largest payload taken for a message start: Ping360 pings hold at most 1200 samples; a larger
#: length is a 'BR' inside other bytes, and refusing it bounds the bytes held while resynchronising.
MAX_PAYLOAD = 16384
#: Ping360 messages of one ping: id -> (struct format of the fixed part, field names). ``data`` follows.
PING_MESSAGES = {
    2300: ('<BBHHHHHH', ('mode', 'gain_setting', 'angle', 'transmit_duration', 'sample_period',
                         'transmit_frequency', 'number_of_samples', 'data_length')),
    2301: ('<BBHHHHHHBBHH', ('mode', 'gain_setting', 'angle', 'transmit_duration', 'sample_period',
                             'transmit_frequency', 'start_angle', 'stop_angle', 'num_steps', 'delay',
                             'number_of_samples', 'data_length')),
}


def time_of_day_ns(text: str) -> int | None:
    """Nanoseconds since midnight of a time ``hh:mm:ss[.fff]`` written in any Unicode decimal digits
    and separators; None when it is not such a time."""
    groups: list[str] = []
    current = ''
    for ch in text:
        digit = unicodedata.decimal(ch, None)
        if digit is not None:
            current += str(digit)
        elif current:
            groups.append(current)
            current = ''
    if current:
        groups.append(current)
    if len(groups) not in (3, 4) or any(len(g) > 2 for g in groups[:3]) or len(groups[-1]) > 9:
        return None
    h, m, s = (int(g) for g in groups[:3])
    if h > 23 or m > 59 or s > 60:
        return None
    frac = int(groups[3].ljust(9, '0')) if len(groups) == 4 else 0
    return ((h * 60 + m) * 60 + s) * 10**9 + frac


@dataclass(frozen=True)
class _Message:
    """A ping-protocol message cut from the stream: where it starts in the stream, id and payload."""

    offset: int
    message_id: int
    payload: bytes


class PingStream:
    """Bytes in, ping-protocol messages out, whatever the chunks' boundaries.

    Work per byte is bounded: a candidate start whose length exceeds :data:`MAX_PAYLOAD` or whose
    checksum fails is dropped by one byte and the search goes on.
    """

    def __init__(self) -> None:
        self.buffer = bytearray()
        self.base = 0              # stream offset of buffer[0]
        self.skipped = 0           # bytes outside any message
        self.bad_checksums = 0

    def feed(self, chunk: bytes) -> Iterator[_Message]:
        """The messages completed by ``chunk``. A candidate start is held until its length and
        checksum can be checked (at most :data:`MAX_PAYLOAD` + 10 bytes); when its checksum fails the
        bytes after its first are searched again, so the messages it covered are not lost."""
        buf = self.buffer
        buf += chunk
        while True:
            start = buf.find(b'BR')
            if start < 0:
                keep = 1 if buf[-1:] == b'B' else 0
                self._drop(len(buf) - keep)
                return
            if start:
                self._drop(start)
            if len(buf) < 8:
                return
            length, message_id = struct.unpack_from('<HH', buf, 2)
            if length > MAX_PAYLOAD:
                self._drop(1)
                continue
            end = 8 + length
            if len(buf) < end + 2:
                return
            if (sum(memoryview(buf)[:end]) & 0xFFFF) != struct.unpack_from('<H', buf, end)[0]:
                self.bad_checksums += 1
                self._drop(1)
                continue
            yield _Message(self.base, message_id, bytes(buf[8:end]))
            del buf[:end + 2]
            self.base += end + 2

    def finish(self) -> Iterator[_Message]:
        """The messages still in the buffer when the stream has ended: a candidate start waiting for
        bytes that never came is dropped by one byte at a time and the search goes on."""
        while self.buffer:
            self._drop(1)
            yield from self.feed(b'')

    def _drop(self, n: int) -> None:
        del self.buffer[:n]
        self.base += n
        self.skipped += n


@dataclass(frozen=True)
class _Record:
    start: int        # byte of the file
    text: str         # its time as written
    offset: int       # stream offset of its first byte
    body: bytes


class PingViewerRecording(Recording):
    """A Ping Viewer ``.bin`` log of a Ping360 (see the module docstring)."""

    kind = 'pingviewer'
    TOPIC = 'ping360'
    _MAGIC = 'PingViewer sensor log file'

    def __init__(self, path: Path, date: str = '') -> None:
        super().__init__(path)
        self.data = path.read_bytes()
        self.header, self.pos = self._header()
        day = date or (m.group(1) if (m := re.search(r'(\d{8})', path.name)) else '19700101')
        try:
            fmt = '%Y-%m-%d' if '-' in day else '%Y%m%d'
            self.day_ns = int(datetime.strptime(day, fmt).replace(tzinfo=timezone.utc).timestamp()) * 1_000_000_000
        except ValueError as exc:
            raise RecordingError(f'date {day!r} is not YYYY-MM-DD') from exc

    def _string(self, pos: int) -> tuple[str, int]:
        """A Qt string (uint32 byte count, 0xFFFFFFFF = null; UTF-16BE, or UTF-8 in some writers) at ``pos``."""
        (n,) = struct.unpack_from('>I', self.data, pos)
        if n == 0xFFFFFFFF:
            return '', pos + 4
        if pos + 4 + n > len(self.data):
            raise struct.error('string runs past the end of the file')
        raw = self.data[pos + 4:pos + 4 + n]
        return _qt_text(raw), pos + 4 + n

    def _header(self) -> tuple[dict, int]:
        try:
            magic, pos = self._string(0)
            if magic != self._MAGIC:
                raise RecordingError(f'{self.path} is not a Ping Viewer log (it starts with {magic[:40]!r})')
            (version,) = struct.unpack_from('>i', self.data, pos)
            pos += 4
            info = []
            for _ in range(5):
                s, pos = self._string(pos)
                info.append(s)
            family, sensor = struct.unpack_from('>ii', self.data, pos)
            pos += 8
        except struct.error as exc:
            raise RecordingError(f'{self.path}: the Ping Viewer header is cut off ({exc})') from exc
        return {'version': version, 'build': info, 'family': family, 'type': sensor}, pos

    def _records(self) -> list[_Record]:
        """Every complete record; a cut-off last record is reported."""
        out: list[_Record] = []
        pos, offset = self.pos, 0
        while pos < len(self.data):
            start = pos
            try:
                text, pos = self._string(pos)
                (n,) = struct.unpack_from('>I', self.data, pos)
                if pos + 4 + n > len(self.data):
                    raise struct.error('message runs past the end of the file')
                body = self.data[pos + 4:pos + 4 + n]
                pos += 4 + n
            except struct.error:
                last = out[-1].text if out else 'the header'
                self.problem(self.TOPIC, 0, f'the file is cut off: the record at byte {start} of {len(self.data)} '
                                            f'is incomplete; the records up to {last} were imported')
                break
            out.append(_Record(start, text, offset, body))
            offset += len(body)
        return out

    def _times(self, records: list[_Record]) -> list[int] | None:
        """Each record's stamp [ns], or None when no record's time can be read."""
        tods = [time_of_day_ns(r.text) for r in records]
        readable = [i for i, t in enumerate(tods) if t is not None]
        if not readable:
            return None
        bad = len(records) - len(readable)
        if bad:
            first = next(i for i, t in enumerate(tods) if t is None)
            self.problem(self.TOPIC, 0, f'{bad} of {len(records)} record times cannot be read (the first: '
                                        f'{records[first].text!r} at byte {records[first].start}); their bytes '
                                        'take the time of the record before them')
        out: list[int] = []
        day, last = self.day_ns, int(tods[readable[0]] or 0)
        for tod in tods:
            if tod is None:
                tod = last
            elif tod < last - DAY_NS // 2:
                day += DAY_NS
            last = tod
            out.append(day + tod)
        return out

    def _messages(self) -> Iterator[tuple[int, _Message]]:
        """``(stamp_ns or -1, message)`` of every message in the stream; -1 = no record time readable."""
        records = self._records()
        times = self._times(records)
        stream = PingStream()
        k = 0

        def stamped(messages: Iterator[_Message]) -> Iterator[tuple[int, _Message]]:
            nonlocal k
            for msg in messages:
                while k + 1 < len(records) and records[k + 1].offset <= msg.offset:
                    k += 1
                yield (times[k] if times is not None else -1), msg
        for rec in records:
            yield from stamped(stream.feed(rec.body))
        tail = len(stream.buffer)
        yield from stamped(stream.finish())
        if stream.skipped:
            what = f'{stream.skipped} bytes outside ping messages skipped'
            if stream.bad_checksums:
                what += f' ({stream.bad_checksums} candidate messages had a wrong checksum)'
            if tail:
                what += f'; the stream ends {tail} bytes into an incomplete message'
            self.problem(self.TOPIC, 0, what)

    def topics(self) -> list[TopicInfo]:
        counts: dict[int, int] = {}
        for _, msg in self._messages():
            counts[msg.message_id] = counts.get(msg.message_id, 0) + 1
        self.problems.clear()
        return [TopicInfo(self.TOPIC, f'ping-protocol id {mid}', c, 'echo' if mid in PING_MESSAGES else '')
                for mid, c in sorted(counts.items())]

    def describe(self) -> list[str]:
        h = self.header
        known = len(self.problems)
        records = self._records()
        readable = sum(time_of_day_ns(r.text) is not None for r in records)
        del self.problems[known:]        # items() reports a cut-off file when it reads the records
        return [f'Ping Viewer log version {h["version"]}, sensor family {h["family"]} type {h["type"]}: '
                f'{len(records)} records, {readable} with a readable time'
                + ('' if readable else ' (pings will be stamped in order at their sample timing)')]

    def sensor(self, options: ImportOptions) -> tuple[Sensor | None, str]:
        return PING360, 'a Ping Viewer log'

    def angle_unit_used(self, options: ImportOptions) -> str:
        return 'grad' if options.angle_unit == 'auto' else options.angle_unit

    def items(self, options: ImportOptions) -> Iterator[Item]:
        unit = self.angle_unit_used(options)
        clock, timed = self.day_ns, True
        for stamp, msg in self._messages():
            layout = PING_MESSAGES.get(msg.message_id)
            if layout is None:
                continue
            fmt, names = layout
            size = struct.calcsize(fmt)
            if len(msg.payload) < size:
                self.problem(self.TOPIC, max(stamp, 0), f'message {msg.message_id} at stream byte {msg.offset} has '
                                                        f'{len(msg.payload)} bytes, fewer than its {size}; skipped')
                continue
            f = dict(zip(names, struct.unpack_from(fmt, msg.payload)))
            samples = np.frombuffer(msg.payload[size:], dtype=np.uint8).copy()
            n_expected = int(f['number_of_samples'])
            count = max(n_expected, len(samples))
            if stamp < 0:   # no time readable: stamped in order at the ping's own timing
                if timed:
                    timed = False
                    self.problem(self.TOPIC, 0, 'no record time can be read: pings are stamped in order from the '
                                                'start of the day at their sample timing (transmit duration + '
                                                'samples x sample period); give --date for the day')
                stamp = clock
                clock += int(round(f['transmit_duration'] * 1e3 + count * f['sample_period'] * TICK * 1e9))
            if count == 0 or f['sample_period'] <= 0:
                self.problem(self.TOPIC, stamp, 'ping without samples or sample period; skipped')
                continue
            r0, r1 = bins_geometry(count, options.speed_of_sound * f['sample_period'] * TICK / 2.0)
            bearing = head_bearing(float(f['angle']), unit, options)
            yield Item('ping', self.TOPIC, stamp,
                       Ping(stamp, stamp, bearing, samples, r0, r1, n_expected,
                            settings=(int(f['sample_period']), n_expected)))


def _qt_text(raw: bytes) -> str:
    """Text of a Qt string's bytes: UTF-16BE (what QDataStream writes) when it holds a NUL byte or is
    not UTF-8, else UTF-8."""
    if len(raw) % 2 == 0:
        utf8 = True
        try:
            raw.decode('utf-8')
        except UnicodeDecodeError:
            utf8 = False
        if b'\x00' in raw or not utf8:
            try:
                return raw.decode('utf-16-be')
            except UnicodeDecodeError:
                pass
    return raw.replace(b'\x00', b'').decode('utf-8', 'replace')
