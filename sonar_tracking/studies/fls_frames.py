"""Simulated FLS frames for tracking studies, with each target's true state *as imaged*.

A SeaKing image is painted beam by beam over a whole sweep (5 s in the tank, about 10 s at sea),
so a moving target is in the image where it was when the beam crossed it, not where it is at the
frame's stamp (the last sector's). The reference of the FLS paper's CLE (eq. 19) is the target's
centre in the image, so :func:`imaged_truth` gives every target's state at the time of the ping
whose beam pointed at it in that frame (the beam that painted it last): for each ping ``j`` of the
frame, time ``t_j = stamp + j * ping_period`` of its sector and bearing ``angle_min + j * increment``
from the sensor's pose; the target's bearing is found at the frame's mid time, the ping nearest in
bearing chosen, the target's bearing recomputed at that ping's time and the choice made again
(the target moves little in bearing during a ping).

:func:`processed_frames` is the one loop from the simulator to FLS frames: it feeds a scenario's
sectors (decoded to linear amplitude) to :class:`~..fls.pipeline.FlsProcessor` (the
``fls_features`` pipeline) and yields every frame with the sectors it was built from.
:func:`simulate_tracking_frames` returns a scenario's frames with their imaged truth;
:func:`~.fls_segmentation.simulate_frames` labels them with the targets' footprints.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from sonar_tracking.core.fls.pipeline import FlsConfig, FlsFrame, FlsProcessor
from sonar_tracking.core.intensity import decode
from sonar_tracking.sim import OutputConfig, SimConfig, Simulator
from sonar_tracking.sim.sensor import SimSector

__all__ = ['TrackingFrame', 'simulate_tracking_frames', 'imaged_truth', 'ping_table', 'sim_amplitudes',
           'simulator_for', 'processed_frames']


@dataclass(eq=False)
class TrackingFrame:
    """One processed frame and its truth: target ids ``(G,)``, states ``(G, 4)`` ``[x, y, vx, vy]``
    as imaged (see module docstring) and ``imaged_at (G,)`` the times they refer to [s]."""

    frame: FlsFrame
    ids: np.ndarray
    truth: np.ndarray
    imaged_at: np.ndarray

    @property
    def stamp(self) -> float:
        return self.frame.stamp


def ping_table(sectors: list[SimSector]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every ping of the sectors: times ``(P,)``, world bearings ``(P,)`` and sensor positions ``(P, 2)``."""
    times, bearings, xy = [], [], []
    for s in sectors:
        g = s.geometry
        j = np.arange(g.n_beams)
        t = s.stamp + j * g.ping_period
        x, y, yaw = s.pose
        times.append(t)
        bearings.append(yaw + g.angle_min + j * g.angle_increment)
        xy.append(np.broadcast_to((x, y), (g.n_beams, 2)))
    if not times:
        return np.zeros(0), np.zeros(0), np.zeros((0, 2))
    return np.concatenate(times), np.concatenate(bearings), np.concatenate(xy)


def imaged_truth(sim: Simulator, sectors: list[SimSector]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Target ids, states as imaged by the pings of ``sectors`` and the times they refer to."""
    ids, _ = sim.truth(0.0)
    t, b, xy = ping_table(sectors)
    states = np.zeros((len(ids), 4))
    when = np.zeros(len(ids))
    if t.size == 0:
        return ids, states, when
    t_mid = 0.5 * (t.min() + t.max())
    for g, target in enumerate(sim.scene.targets):
        tj = t_mid
        for _ in range(2):
            s = target.trajectory.state(tj)
            j = int(np.argmin(np.abs(np.remainder(np.arctan2(s[1] - xy[:, 1], s[0] - xy[:, 0]) - b + math.pi,
                                                  2 * math.pi) - math.pi)))
            tj = float(t[j])
        states[g] = target.trajectory.state(tj)
        when[g] = tj
    return ids, states, when


def sim_amplitudes(sector: SimSector, output: OutputConfig) -> np.ndarray:
    """A simulated sector's values as the simulator's linear amplitude: 8-bit dB counts decoded
    (``intensity.decode``) and scaled back by the gain floor, 0 staying 0; float values as they are."""
    if output.coding != 'db':
        return sector.amplitudes
    return decode(sector.amplitudes, 'db', db_span=output.db_span, full_scale=255.0) * output.gain_floor


def simulator_for(scenario: str, seed: int | np.random.SeedSequence, preset: str = '', **sim_overrides) -> Simulator:
    """The simulator of a SeaKing scenario seeded ``seed``; ``sim_overrides`` are flat SimConfig settings."""
    cfg = SimConfig.for_scenario(scenario, preset, **sim_overrides)
    if cfg.is_harbour:
        raise ValueError(f'scenario {scenario} on the harbour sonar has no FLS images; use a SeaKing preset')
    return Simulator(cfg, np.random.default_rng(seed))


def processed_frames(sim: Simulator, processor: FlsProcessor, on_sector: Callable[[SimSector], Any] | None = None
                     ) -> Iterator[tuple[FlsFrame, list[tuple[SimSector, Any]]]]:
    """Every frame (whole sweep) of ``sim`` processed by ``processor``, with its member sectors, each
    paired with what ``on_sector(sector)`` returned when the sector arrived (None without it).
    Sectors in 8-bit dB output (structured scenarios) are decoded to linear amplitude first."""
    pending: list[tuple[SimSector, Any]] = []
    while (sector := sim.next_sector()) is not None:
        pending.append((sector, on_sector(sector) if on_sector is not None else None))
        values = sim_amplitudes(sector, sim.config.output)
        for frame in processor.add_sector(values, sector.geometry, sector.pose, sector.stamp):
            members, pending = pending[:frame.sectors], pending[frame.sectors:]
            yield frame, members


def simulate_tracking_frames(scenario: str, seed: int | np.random.SeedSequence, config: FlsConfig | None = None,
                             preset: str = '', **sim_overrides) -> list[TrackingFrame]:
    """All frames of a SeaKing scenario (:func:`processed_frames`), each with its imaged truth.
    ``sim_overrides`` are flat SimConfig settings."""
    sim = simulator_for(scenario, seed, preset, **sim_overrides)
    out: list[TrackingFrame] = []
    for frame, members in processed_frames(sim, FlsProcessor(config)):
        ids, states, when = imaged_truth(sim, [sector for sector, _ in members])
        out.append(TrackingFrame(frame, ids, states, when))
    return out
