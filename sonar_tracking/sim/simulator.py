"""The simulator: a scenario's scene seen by one sensor, sector after sector.

The sensor follows the preset: the harbour sonar (:class:`HarbourSonar`), a SeaKing
(:class:`SeaKingSonar`) or a multibeam imaging sonar (:class:`ImagingSonar`: ``oculus_m750d``,
``gemini_720``, ``aris3000``, one frame per sector).

:class:`SimConfig` is the whole configuration (what ``seaking_sim`` exposes as parameters);
:meth:`SimConfig.for_scenario` gives a scenario's defaults (sensor preset, clutter rate, SNR,
duration, sensor window). :class:`Simulator` draws the scene's random parts and the per-sector
noise from two independent streams, so changing how pings are grouped into sectors never changes
where the targets go. The streams are the first two children of the injected generator's
``SeedSequence`` (:func:`child_generators`), derived without spawning: a simulation is a function of
the seed the generator was built from alone, and two simulators given one generator object are
identical (``Generator.spawn`` would advance the shared sequence and give the second other sectors).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.records import TRUTH_DTYPE
from sonar_tracking.sim.amplitude import AmplitudeConfig, AmplitudeModel
from sonar_tracking.sim.harbour import HarbourConfig, HarbourSonar
from sonar_tracking.sim.imaging import ImagingConfig, ImagingSonar
from sonar_tracking.sim.presets import (
    IMAGING_PRESETS,
    SCENARIOS,
    SENSOR_PRESETS,
    STRUCTURE_PRESETS,
    build_scene,
    scenario_info,
)
from sonar_tracking.sim.scene import Scene
from sonar_tracking.sim.seaking import SeaKingConfig, SeaKingSonar
from sonar_tracking.sim.sensor import SimSector
from sonar_tracking.sim.structure import OutputConfig, StructureConfig, build_structure, decode_output, encode_output

__all__ = ['SimConfig', 'Simulator', 'child_seeds', 'child_generators']


@dataclass(frozen=True)
class SimConfig(Config):
    """Scenario, sensor and clutter settings of the simulator."""

    scenario: str = setting('scenario2', 'scenario preset (ESC scenario1/2, FLS fls1..fls14, sea_trial, clutter; '
                            '*_structured and structure_only add walls, seabed, ringdown and 8-bit dB output; '
                            'imaging_* for the imaging sonars)', choices=tuple(SCENARIOS), read_only=True)
    preset: str = setting('harbour', 'sensor preset', choices=tuple(SENSOR_PRESETS), read_only=True)
    seed: int = setting(0, 'random seed: same seed, same messages', low=0, high=2**63 - 1, read_only=True)
    sector_size: int = setting(10, 'pings per published sector (SeaKing; a harbour scan or an imaging frame is '
                               'one sector)', low=1, high=8000, read_only=True)
    duration: float = setting(100.0, 'scenario length, 0 = no end', unit='s', low=0.0, read_only=True)
    clutter_lambda: float = setting(1.6, 'clutter rate lam of eq. (15) outside any clutter region',
                                    low=1e-3, high=1e3)
    snr_db: float = setting(8.0, 'target signal-to-noise ratio', unit='dB', low=-20.0, high=60.0)
    amplitude: AmplitudeConfig = dataclasses.field(default_factory=AmplitudeConfig)
    harbour: HarbourConfig = dataclasses.field(default_factory=HarbourConfig)
    seaking: SeaKingConfig = dataclasses.field(default_factory=SeaKingConfig)
    imaging: ImagingConfig = dataclasses.field(default_factory=ImagingConfig)
    structure: StructureConfig = dataclasses.field(default_factory=StructureConfig)
    output: OutputConfig = dataclasses.field(default_factory=OutputConfig)

    def validate(self) -> None:
        info = scenario_info(self.scenario)
        if self.preset not in info.sensors:
            raise ConfigError(f'scenario {self.scenario} runs on {"/".join(info.sensors)}, not preset {self.preset}')
        kind = self.structure.kind
        if kind != 'none' and (kind == 'harbour') != self.is_harbour:
            where = 'harbour' if kind == 'harbour' else 'SeaKing (tank)'
            raise ConfigError(f'structure.kind = {kind} is laid out for the {where} sensor, not preset {self.preset}')

    @classmethod
    def for_scenario(cls, scenario: str, preset: str = '', **flat) -> SimConfig:
        """Defaults of ``scenario`` on ``preset`` ('' = the scenario's sensor), then ``flat`` overrides."""
        try:
            info = scenario_info(scenario)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        preset = preset or info.sensors[0]
        if preset not in SENSOR_PRESETS:
            raise ConfigError(f'unknown sensor preset {preset!r}; known: {sorted(SENSOR_PRESETS)}')
        values = {'scenario': scenario, 'preset': preset, 'duration': info.duration,
                  'clutter_lambda': info.clutter_lambda, 'snr_db': info.snr_db}
        values.update(SENSOR_PRESETS[preset])
        values.update(dict(info.overrides))
        if info.structured:
            values.update(STRUCTURE_PRESETS['harbour' if preset == 'harbour' else 'tank'])
        values.update(flat)
        return cls.from_flat(values)

    @property
    def is_harbour(self) -> bool:
        return self.preset == 'harbour'

    @property
    def is_imaging(self) -> bool:
        """Whether the sensor is a multibeam imaging sonar (:class:`ImagingSonar`)."""
        return self.preset in IMAGING_PRESETS


def child_seeds(seq: np.random.SeedSequence, n: int) -> list[np.random.SeedSequence]:
    """The first ``n`` children of ``seq``, as ``seq.spawn(n)`` gives them on a fresh sequence, but
    without changing ``seq`` (``spawn`` counts its children, so a second call gives others)."""
    return [np.random.SeedSequence(seq.entropy, spawn_key=tuple(seq.spawn_key) + (i,), pool_size=seq.pool_size)
            for i in range(n)]


def child_generators(rng: np.random.Generator, n: int) -> list[np.random.Generator]:
    """``n`` independent generators from the first children of ``rng``'s seed sequence
    (:func:`child_seeds`); ``rng`` and its sequence are left as they are."""
    seq = rng.bit_generator.seed_seq
    if not isinstance(seq, np.random.SeedSequence):
        raise TypeError('the simulator needs a generator built from a seed, e.g. numpy.random.default_rng(seed)')
    return [np.random.Generator(type(rng.bit_generator)(s)) for s in child_seeds(seq, n)]


class Simulator:
    """Sectors of a scenario; ``next_sector()`` returns None once the scenario has ended."""

    def __init__(self, config: SimConfig, rng: np.random.Generator) -> None:
        self.config = config
        scene_rng, self.noise_rng = child_generators(rng, 2)
        self.scene: Scene = build_scene(config.scenario, scene_rng, config.clutter_lambda, config.snr_db,
                                        config.duration, config.preset)
        # Drawn after the targets, so a structured scene has the same targets as its plain one. A
        # scenario that lays out its own structure (imaging_harbour) keeps it unless one is asked for.
        if config.structure.kind != 'none' or self.scene.structure is None:
            self.scene.structure = build_structure(config.structure, scene_rng)
        amplitude = AmplitudeModel(config.amplitude)
        self.sensor: HarbourSonar | SeaKingSonar | ImagingSonar
        if config.is_harbour:
            self.sensor = HarbourSonar(config.harbour, amplitude)
        elif config.is_imaging:
            self.sensor = ImagingSonar(config.imaging)
        else:
            self.sensor = SeaKingSonar(config.seaking, config.sector_size, amplitude)

    @property
    def finished(self) -> bool:
        """Whether the next sector would start after the end of the scenario."""
        return self.sensor.next_time > self.scene.duration + 1e-9

    def next_sector(self) -> SimSector | None:
        """The next sector, or None after the scenario's duration.

        Its values are float32 linear amplitudes, or uint8 dB counts with ``output.coding = db``.
        """
        if self.finished:
            return None
        sector = self.sensor.next_sector(self.scene, self.noise_rng)
        if self.config.output.coding == 'linear_amplitude':
            return sector
        return dataclasses.replace(sector, amplitudes=encode_output(sector.amplitudes, self.config.output))

    def truth(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Target ids and world states ``[x, y, vx, vy]`` at ``t``."""
        return self.scene.truth(t)

    def truth_records(self, t: float) -> np.ndarray:
        """The targets at ``t`` as ``TRUTH_DTYPE`` records (what ``sonar/truth`` carries)."""
        ids, states = self.scene.truth(t)
        out = np.zeros(len(ids), TRUTH_DTYPE)
        out['target_id'] = ids
        out['x'], out['y'], out['vx'], out['vy'] = states.T
        return out

    def linear(self, values: np.ndarray) -> np.ndarray:
        """A sector's values as :meth:`next_sector` gives them, back to linear amplitude (for pictures)."""
        return decode_output(values, self.config.output)

    def set_clutter_lambda(self, lam: float) -> None:
        """Change the background clutter rate from the next sector on."""
        self.scene.lam = float(lam)

    def set_snr_db(self, snr_db: float) -> None:
        """Change every target's SNR from the next sector on."""
        for target in self.scene.targets:
            target.snr_db = float(snr_db)

    @property
    def sweep_period(self) -> float:
        """Time of a full image: a harbour scan, a SeaKing sweep or an imaging-sonar frame [s]."""
        if isinstance(self.sensor, HarbourSonar):
            return self.config.harbour.scan_period
        if isinstance(self.sensor, ImagingSonar):
            return self.config.imaging.frame_period
        return self.config.seaking.sweep_time


def describe(config: SimConfig) -> str:
    """One line for logs: scenario, sensor, sizes and timing (and structure and output coding when set)."""
    extra = ''
    if config.structure.kind != 'none':
        extra += f'; {config.structure.kind} structure'
    if config.output.coding == 'db':
        extra += f'; 8-bit dB output ({config.output.db_span:g} dB span, gain floor {config.output.gain_floor:g})'
    if config.is_imaging:
        m = config.imaging
        law = 'Rayleigh' if m.clutter == 'rayleigh' else f'K (shape {m.k_shape:g})'
        return (f'{config.scenario} on {config.preset}: {m.n_beams} beams over {m.fov_deg:g} deg '
                f'({m.beam_width_deg:g} deg beams, sidelobes {m.sidelobe_db:g} dB) x {m.n_bins} bins '
                f'{m.range_min:g}-{m.range_max:g} m, {m.frame_rate:g} frames/s, {law} speckle, seabed beyond '
                f'{m.grazing_range:.1f} m{extra}')
    if config.is_harbour:
        g = config.harbour.geometry()
        return (f'{config.scenario} on the harbour sonar: {g.n_bins} x {g.n_beams} cells of '
                f'{config.harbour.cell_depth:.2f} m x {math.degrees(config.harbour.cell_width):.3f} deg, '
                f'one scan every {config.harbour.scan_period:g} s{extra}')
    s = config.seaking
    return (f'{config.scenario} on SeaKing {s.frequency_khz:g} kHz: {s.n_bins} bins to {s.range_max:g} m, '
            f'step {s.step_deg:g} deg, ping every {s.ping_period * 1e3:.1f} ms, sweep {s.sweep_time:.2f} s{extra}')
