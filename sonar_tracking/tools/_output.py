"""Writing the results of the ``sonar_eval`` studies: JSON and plots, each path announced."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable

__all__ = ['write_json', 'write_plot']


def write_json(path: Path, data: Any, allow_nan: bool = True) -> None:
    """``data`` as indented JSON at ``path`` (parent folders made); prints ``wrote PATH``.
    ``allow_nan=False`` refuses NaN and infinity, which strict JSON readers reject."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1, allow_nan=allow_nan) + '\n')
    print(f'wrote {path}')


def write_plot(path: Path, draw: Callable[[Any, Path], None], result: Any) -> None:
    """``draw(result, path)``; prints ``wrote PATH``."""
    draw(result, path)
    print(f'wrote {path}')
