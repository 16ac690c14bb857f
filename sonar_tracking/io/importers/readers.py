"""The reader of a recording, chosen by the form of its path."""
from __future__ import annotations

from pathlib import Path

from sonar_tracking.io.importers.frame_folder import FRAME_SUFFIXES, FolderRecording, missing_yaml_text
from sonar_tracking.io.importers.ping_viewer import PingViewerRecording
from sonar_tracking.io.importers.recording import Recording, RecordingError
from sonar_tracking.io.importers.ros_bag import BagRecording

__all__ = ['open_recording']


def open_recording(path: str | Path, date: str = '') -> Recording:
    """The reader for ``path`` by its form: ``.bag`` (ROS 1), ``.bin`` (Ping Viewer), a folder with
    ``sonar.yaml`` (frames), else a ROS 2 bag (directory, ``.mcap``, ``.db3``); a folder that is
    neither says which it lacks."""
    path = Path(path)
    if not path.exists():
        raise RecordingError(f'{path} does not exist')
    if path.is_file() and path.suffix == '.bag':
        return BagRecording(path, ros1=True)
    if path.is_file() and path.suffix == '.bin':
        return PingViewerRecording(path, date)
    if path.is_dir() and (path / 'sonar.yaml').exists():
        return FolderRecording(path)
    if path.is_dir() and not (path / 'metadata.yaml').exists():
        # A recorder that was killed writes no metadata: read its MCAP file directly.
        files = sorted(path.glob('*.mcap'))
        if len(files) == 1:
            path = files[0]
        elif files:
            raise RecordingError(f'{path} has no metadata.yaml and {len(files)} MCAP files; import them one by one')
        elif not any(path.glob('*.db3')):
            if any(p.suffix.lower() in FRAME_SUFFIXES for p in path.iterdir()):
                raise RecordingError(missing_yaml_text(path))
            raise RecordingError(f'{path} is neither a ROS 2 bag (no metadata.yaml, .mcap or .db3 file) nor a folder '
                                 f'of frames (no sonar.yaml and no {"/".join(FRAME_SUFFIXES)} files)')
    return BagRecording(path, ros1=False)
