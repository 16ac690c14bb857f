"""The confirmation threshold T_c swept after the runs, from each track's existence history.

A track counts as confirmed at scan k for threshold T once its existence has exceeded T
(confirmation is kept, as in the tracker). The tracker itself confirms at the grid's smallest T
during the runs, so one run serves every T_c instead of the ESC paper's repeated Monte Carlo for
every T_c (Algorithm 1, lines 7-14). It is a screen, not the system at T_c: a tracker that confirms
at T_c during the run starts tracks only from detections no confirmed track validated, and
Scenario 2's ESC measures the clutter at the confirmed track of highest existence, so the runs at
T_c differ (docs/experiments/2026-11-27-evidence.md); :mod:`.esc_table` checks the screened T_c
inside the run.
"""
from __future__ import annotations

import numpy as np

__all__ = ['T_GRID', 'ConfirmationSweep']

#: Confirmation thresholds swept: 0.50 to 0.99 by 0.01, then 1 - 10^-x for x from 2 to 4 by 0.1
#: (false tracks need T_c close to 1).
T_GRID = np.concatenate([np.round(np.arange(0.50, 0.99, 0.01), 2), 1.0 - 10.0 ** -np.arange(2.0, 4.05, 0.1)])


class ConfirmationSweep:
    """Per scan and per T of :data:`T_GRID`: is a true track confirmed, how many false ones are."""

    def __init__(self) -> None:
        self.best: dict[int, float] = {}   # track id -> highest existence so far

    def update(self, track_ids, existence, label: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``label`` per track (1 true, -1 false, 0 neither, as ``classify_tracks``); returns
        ``has_ctt (T,)`` and ``n_false (T,)`` of this scan."""
        ex = np.empty(len(label))
        for i, (tid, e) in enumerate(zip(list(track_ids), list(existence))):
            self.best[tid] = ex[i] = max(self.best.get(tid, 0.0), e)
        over = ex[:, None] > T_GRID[None, :]                                  # (tracks, T)
        return (over & (label == 1)[:, None]).any(axis=0), (over & (label == -1)[:, None]).sum(axis=0)
