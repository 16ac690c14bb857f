"""Ping Viewer ``.bin`` logs of a Ping360."""
from __future__ import annotations

import re
import struct
from collections.abc import Iterator
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

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

__all__ = ['PingViewerRecording']


class PingViewerRecording(Recording):
    """A Ping Viewer ``.bin`` log of a Ping360 (big-endian: header strings and ints, then records of
    a time-of-day string and a ping-protocol message, each an uint32 size + bytes).

    Record times are ``hh:mm:ss.zzz`` without a date: the date comes from ``date`` (``YYYY-MM-DD``),
    else from the first ``YYYYMMDD`` in the file name, else 1970-01-01 (UTC); a time that goes back
    by more than 12 h is the next day. Messages are parsed by the ``bluerobotics-ping`` library
    (``device_data`` 2300 and ``auto_device_data`` 2301); angles are gradians.
    """

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
        (n,) = struct.unpack_from('>I', self.data, pos)
        if n == 0xFFFFFFFF:
            return '', pos + 4
        if pos + 4 + n > len(self.data):
            raise struct.error('string runs past the end of the file')
        return self.data[pos + 4:pos + 4 + n].replace(b'\x00', b'').decode('utf-8', 'replace'), pos + 4 + n

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

    def _records(self) -> Iterator[tuple[int, str, bytes]]:
        pos, last = self.pos, ''
        while pos < len(self.data):
            start = pos
            try:
                stamp, pos = self._string(pos)
                (n,) = struct.unpack_from('>I', self.data, pos)
                if pos + 4 + n > len(self.data):
                    raise struct.error('message runs past the end of the file')
                body = self.data[pos + 4:pos + 4 + n]
                pos += 4 + n
            except struct.error:
                self.problem(self.TOPIC, 0, f'the file is cut off: the record at byte {start} of {len(self.data)} '
                                            f'is incomplete; the records up to {last or "the header"} were imported')
                return
            last = stamp
            yield start, stamp, body

    def _messages(self) -> Iterator[tuple[int, str, Any]]:
        from brping import PingParser
        parser = PingParser()
        for start, stamp, body in self._records():
            msg = None
            for byte in body:
                if parser.parse_byte(byte) == parser.NEW_MESSAGE:
                    msg = parser.rx_msg
                    break
            if msg is None:
                self.problem(self.TOPIC, 0, f'record at byte {start} ({stamp}) holds no complete ping message')
                continue
            yield start, stamp, msg

    def topics(self) -> list[TopicInfo]:
        counts: dict[int, int] = {}
        for _, _, msg in self._messages():
            counts[msg.message_id] = counts.get(msg.message_id, 0) + 1
        self.problems.clear()
        return [TopicInfo(self.TOPIC, f'ping-protocol id {mid}', c, 'echo' if mid in (2300, 2301) else '')
                for mid, c in sorted(counts.items())]

    def items(self, options: ImportOptions) -> Iterator[Item]:
        unit = 'grad' if options.angle_unit == 'auto' else options.angle_unit
        day, last = self.day_ns, -1
        for start, text, msg in self._messages():
            if msg.message_id not in (2300, 2301):
                continue
            try:
                h, mnt, s = text.strip().split(':')
                tod = int(round((int(h) * 3600 + int(mnt) * 60 + float(s)) * 1e9))
            except ValueError:
                self.problem(self.TOPIC, 0, f'record at byte {start}: time {text!r} is not hh:mm:ss.zzz; skipped')
                continue
            if last >= 0 and tod < last - 12 * 3600 * 10**9:
                day += 86400 * 10**9
            last = tod
            stamp = day + tod
            samples = np.frombuffer(bytes(msg.data), dtype=np.uint8).copy()
            n = max(int(msg.number_of_samples), len(samples))
            if n == 0 or msg.sample_period <= 0:
                self.problem(self.TOPIC, stamp, 'ping without samples or sample period; skipped')
                continue
            r0, r1 = bins_geometry(n, options.speed_of_sound * msg.sample_period * 25e-9 / 2.0)
            bearing = head_bearing(float(msg.angle), unit, options)
            yield Item('ping', self.TOPIC, stamp,
                       Ping(stamp, stamp, bearing, samples, r0, r1, int(msg.number_of_samples)))
