"""Where the package's data files are, however it was installed (no ROS needed to find them).

Parameter files and tables live in ``config/`` of the source tree; ``colcon`` and ``pip``
install them into ``share/sonar_tracking/config``. Search order: ``$SONAR_TRACKING_CONFIG``, the
source tree (editable installs, running from a checkout), then ``share/sonar_tracking/config``
next to the installed package (colcon prefix) or under ``sys.prefix`` (pip).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ['config_path', 'config_dirs']


def config_dirs() -> list[Path]:
    """Candidate ``config`` directories, most specific first."""
    here = Path(__file__).resolve().parent
    dirs = []
    if os.environ.get('SONAR_TRACKING_CONFIG'):
        dirs.append(Path(os.environ['SONAR_TRACKING_CONFIG']))
    dirs.append(here.parent / 'config')
    for parent in here.parents:
        dirs.append(parent / 'share' / 'sonar_tracking' / 'config')
    dirs.append(Path(sys.prefix) / 'share' / 'sonar_tracking' / 'config')
    return dirs


def config_path(name: str) -> Path:
    """The first existing ``config/name``; FileNotFoundError lists where it looked."""
    tried = []
    for d in config_dirs():
        p = d / name
        if p.is_file():
            return p
        tried.append(str(d))
    raise FileNotFoundError(f'{name} not found in any of: {", ".join(tried)}')
