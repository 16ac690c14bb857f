"""Facts of the bag files that the reader, the writer and the repair share."""
from __future__ import annotations

__all__ = ['MCAP_MAGIC', 'OPEN_TAIL', 'RECORDER_STATE']

#: Key in the metadata's ``custom_data`` saying whether the recorder closed the bag.
RECORDER_STATE = 'recorder_state'
MCAP_MAGIC = b'\x89MCAP0\r\n'
#: DataEnd (no CRC) and a footer without summary: a file ending here is a complete MCAP file.
OPEN_TAIL = (b'\x0f' + (4).to_bytes(8, 'little') + bytes(4)
             + b'\x02' + (20).to_bytes(8, 'little') + bytes(20) + MCAP_MAGIC)
