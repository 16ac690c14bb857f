"""A GPF track: its Gaussian (or, for the SIR baseline, its particles), template and bookkeeping."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.gpf.fusion import MF
from sonar_tracking.core.records import GPF_TRACK_DTYPE

__all__ = ['GpfTrack', 'tracks_to_records']


@dataclass(eq=False)
class GpfTrack:
    """One target's track.

    ``mean (4,)`` and ``cov (4, 4)`` are the state ``[x, y, vx, vy]`` and its covariance at
    ``stamp``: the posterior after the last frame (the prior, widened, when that frame did not see
    the target). ``template (m,)`` holds the transformed cue values S_m of eq. (13).
    ``last_weights`` are the normalised particle weights of the last update, ``observed`` the cue
    values at the last estimate; ``particles``/``weights`` are used by the SIR baseline only.
    ``outside_since`` is the stamp of the first frame of the current run of frames in which the
    estimate lay outside the sonar's coverage (None while it is inside).
    """

    track_id: int
    mean: np.ndarray
    cov: np.ndarray
    template: np.ndarray | None        # None: measured again at the next update (the cue set changed)
    born: float
    stamp: float
    last_seen: float
    hits: int = 1
    confirmed: bool = False
    seen: bool = True
    misses: int = 0
    fusion: int = MF
    match: float = 0.0
    distinct: float = 0.0
    a: np.ndarray | None = None
    inverse_spread: np.ndarray | None = None
    last_weights: np.ndarray | None = None
    observed: np.ndarray | None = None
    weights: np.ndarray | None = None
    particles: np.ndarray | None = None
    template_updates: int = 0
    outside_since: float | None = None

    @property
    def position(self) -> np.ndarray:
        return self.mean[:2]


def tracks_to_records(tracks: list) -> np.ndarray:
    """GPF_TRACK_DTYPE records of tracks (anything with the attributes of :class:`GpfTrack`)."""
    rec = np.zeros(len(tracks), GPF_TRACK_DTYPE)
    for i, t in enumerate(tracks):
        rec[i]['track_id'] = t.track_id
        rec[i]['x'], rec[i]['y'], rec[i]['vx'], rec[i]['vy'] = t.mean
        rec[i]['confirmed'] = 1 if t.confirmed else 0
        rec[i]['fusion'] = t.fusion
        rec[i]['cov_xx'], rec[i]['cov_xy'], rec[i]['cov_yy'] = t.cov[0, 0], t.cov[0, 1], t.cov[1, 1]
        rec[i]['cov_vxvx'], rec[i]['cov_vyvy'] = t.cov[2, 2], t.cov[3, 3]
    return rec
