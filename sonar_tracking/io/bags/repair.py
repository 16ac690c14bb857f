"""Repair of a bag left by a killed recorder: each MCAP file is cut after its last complete record
and given an open tail, each sqlite3 file is checkpointed, and ``metadata.yaml`` is rebuilt from the
files."""
from __future__ import annotations

import os
import sqlite3
from pathlib import Path

from sonar_tracking.io.bags.format import MCAP_MAGIC, OPEN_TAIL
from sonar_tracking.io.bags.reader import McapScan, bag_state
from sonar_tracking.io.bags.writer import RESERVE_NAME, FileStats, bag_metadata, write_metadata

__all__ = ['repair']


def repair(bag: Path | str) -> list[str]:
    """Make a bag left by a killed recorder readable by every reader; returns what was done.

    Each MCAP file is cut after its last complete top-level record (a cut chunk is lost) and
    ends with an open tail; each sqlite3 file is checkpointed back to a single file; the
    metadata is rebuilt from the files (``recorder_state: repaired``). A bag that was closed
    is left as it is.
    """
    bag = Path(bag)
    state = bag_state(bag)
    if not any(f.exists() for f in state.files):
        raise FileNotFoundError(f'{bag} holds no MCAP or sqlite3 file')
    if state.closed:
        return []
    done = []
    for file in (f for f in state.files if f.exists()):
        if file.suffix == '.mcap':
            with open(file, 'r+b') as f:
                scan = McapScan(f, file)
                end, cut = scan.valid_end()
                if cut is not None or not scan.ended or not _ends_properly(f, scan.size):
                    f.truncate(end)
                    f.seek(end)
                    f.write(OPEN_TAIL)
                    f.flush()
                    os.fsync(f.fileno())
                    done.append(f'{file.name}: cut at byte {end} of {scan.size} and ended there')
        elif file.suffix == '.db3':
            con = sqlite3.connect(file)
            try:
                con.execute('PRAGMA wal_checkpoint(TRUNCATE)')
                con.execute('PRAGMA journal_mode=DELETE')
            finally:
                con.close()
            done.append(f'{file.name}: write-ahead log checkpointed')
    (bag / RESERVE_NAME).unlink(missing_ok=True)
    write_metadata(bag, _metadata_from_files(state), sync=True)
    done.append('metadata.yaml rebuilt from the files')
    return done


def _ends_properly(f, size: int) -> bool:
    """The file ends with a footer record and the magic."""
    if size < 8 + 37:
        return False
    f.seek(size - 37)
    data = f.read(37)
    return data[:9] == b'\x02' + (20).to_bytes(8, 'little') and data[-8:] == MCAP_MAGIC


def _metadata_from_files(state) -> dict:
    from rosbags.rosbag2 import Reader
    files, topics = [], {}
    for file in (f for f in state.files if f.exists()):
        stats = FileStats(file.name)
        with Reader(file) as reader:
            for conn in reader.connections:
                if conn.msgcount:
                    stats.add({conn.id: conn.msgcount}, reader.start_time, reader.end_time - 1)
                key = (conn.topic, conn.msgtype)
                prev = topics.get(key)
                topics[key] = (prev[0] if prev else conn, (prev[1] if prev else 0) + conn.msgcount)
        files.append(stats)
    conns = []
    for conn, n in topics.values():
        conns.append((conn._replace(digest=conn.digest or _type_hash(conn.msgtype)), n))
    return bag_metadata(state.storage, files, conns, 'repaired: the recorder did not close the bag')


def _type_hash(msgtype: str) -> str:
    from rosbags.typesys import Stores, get_typestore
    try:
        return get_typestore(Stores.ROS2_JAZZY).hash_rihs01(msgtype)
    except Exception:  # noqa: BLE001 - a type this typestore does not know has no hash to give
        return ''
