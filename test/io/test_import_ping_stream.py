"""The Ping Viewer reader's pieces: record times in any digits, and the ping-protocol byte stream cut
into messages whatever the chunk boundaries, skipping what is not a message."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from sonar_tracking.io.importers.ping_viewer import PingStream, time_of_day_ns

TEN_O_FIVE = ((10 * 60 + 5) * 60 + 7) * 10**9 + 89 * 10**6   # 10:05:07.089


@pytest.mark.parametrize('text', [
    '10:05:07.089',
    '\u06f1\u06f0:\u06f0\u06f5:\u06f0\u06f7\u066b\u06f0\u06f8\u06f9',    # Extended Arabic-Indic, Arabic decimal mark
    '\u0661\u0660:\u0660\u0665:\u0660\u0667.\u0660\u0668\u0669',          # Arabic-Indic
    '\u0967\u0966:\u0966\u096b:\u0966\u096d.\u0966\u096e\u096f',          # Devanagari
    '\uff11\uff10:\uff10\uff15:\uff10\uff17.\uff10\uff18\uff19',          # fullwidth
    ' 10:05:07,089 ',
])
def test_times_in_any_decimal_digits(text):
    assert time_of_day_ns(text) == TEN_O_FIVE


@pytest.mark.parametrize('text', ['', '--:--:--', '25:00:00.000', '10:61:00', '10:05', 'AM', '123:05:07.000'])
def test_what_is_not_a_time(text):
    assert time_of_day_ns(text) is None


def message(message_id: int, payload: bytes) -> bytes:
    head = b'BR' + struct.pack('<HHBB', len(payload), message_id, 0, 0) + payload
    return head + struct.pack('<H', sum(head) & 0xFFFF)


def test_messages_across_chunks_with_noise_and_a_bad_checksum():
    rng = np.random.default_rng(41)
    good = [message(2300, rng.bytes(n)) for n in (14, 1214, 300)]
    bad = bytearray(message(2300, rng.bytes(40)))
    bad[20] ^= 0xFF                                        # a damaged payload: checksum fails
    noise = b'xyBR\x7a\x20' + bytes(6)   # a stray 'BR' announcing 8314 bytes: held, then given up at the end
    stream = noise + good[0] + bytes(bad) + good[1] + b'\x00B' + good[2]
    for sizes in ([1] * len(stream), [len(stream)], list(rng.integers(1, 200, len(stream)))):
        s, got, pos = PingStream(), [], 0
        for n in sizes:
            got += list(s.feed(stream[pos:pos + n]))
            pos += n
            if pos >= len(stream):
                break
        got += list(s.finish())
        assert [m.payload for m in got] == [g[8:-2] for g in good]
        assert [m.offset for m in got] == [stream.index(g) for g in good]
        assert s.bad_checksums >= 1 and s.skipped == len(noise) + len(bad) + 2 and not s.buffer


def test_a_huge_length_is_not_waited_for():
    """A 'BR' whose length field exceeds any ping message is skipped at once, not held while more
    bytes arrive (bounded memory and work per byte)."""
    s = PingStream()
    good = message(2300, b'\x01' * 20)
    assert [m.payload for m in s.feed(b'BR\xff\xff\x00\x00\x00\x00' + good)] == [b'\x01' * 20]
    assert s.skipped == 8


def test_a_sector_never_mixes_sample_periods():
    """Pings whose sample periods differ by one 25 ns tick (ranges equal within 1e-4) are kept apart."""
    from sonar_tracking.io.importers.recording import bins_geometry
    from sonar_tracking.io.importers.sweeps import Ping, SweepAssembler
    asm = SweepAssembler()
    out = []
    for k in range(20):
        period = 40000 if k < 10 else 40001
        r0, r1 = bins_geometry(100, 1500 * period * 25e-9 / 2)
        ping = Ping(k * 10**7, k * 10**7, 0.01 * k, np.full(100, 50, np.uint8), r0, r1, 100, settings=(period, 100))
        out += asm.add(ping)
    out += asm.finish()
    assert [s.n_pings for s in out] == [10, 10]
