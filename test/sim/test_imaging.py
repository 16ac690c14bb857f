"""Multibeam imaging-sonar simulator: speckle law, beam pattern, frozen speckle and its decorrelation,
shadows, structure levels, determinism and the imaging scenarios on every imaging preset.

Statistical tests run on reduced frames (128 beams x 256 bins, beams 4 per beam width as on an
Oculus) with fixed seeds; their thresholds are stated beside them.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from sonar_tracking.core.config import ConfigError
from sonar_tracking.sim import SimConfig, Simulator
from sonar_tracking.sim.imaging import UNIFORM_SIDELOBE_DB, BeamPattern, ImagingConfig, ImagingSonar, k_sf
from sonar_tracking.sim.motion import StaticTrajectory, Trajectory
from sonar_tracking.sim.presets import IMAGING_PRESETS, SENSOR_PRESETS
from sonar_tracking.sim.scene import Scene, Target
from sonar_tracking.sim.shapes import shape
from sonar_tracking.sim.structure import RoughShape, Structure, StructureConfig, Texture

#: Reduced frame: 128 beams 0.254 deg apart (as the Oculus's 512 over 130 deg), 1 deg beams, 256 bins to 10 m.
SMALL = dict(n_beams=128, fov_deg=32.5, beam_width_deg=1.0, n_bins=256, range_min=0.5, range_max=10.0,
             texture_bins=16, texture_beams=8)


def small(**changes) -> ImagingConfig:
    return ImagingConfig(**{**SMALL, **changes})


class Spinning(Trajectory):
    """A platform turning on the spot at ``rate`` [rad/s]."""

    def __init__(self, rate: float) -> None:
        self.rate = rate

    def state(self, t: float) -> np.ndarray:
        return np.zeros(4)

    def heading(self, t: float) -> float:
        return self.rate * t


def normalised_intensity(sensor: ImagingSonar, frame) -> np.ndarray:
    return frame.amplitudes.astype(float) ** 2 / sensor.level[:, None]


def decimated_samples(config: ImagingConfig, frames: int, seed: int) -> np.ndarray:
    """I / L of one cell per texture block (16 bins x 8 beams: also 2 beam widths and 16 range
    resolutions apart), pooled over independent frames (the sensor is reset between frames, so each
    draws a new speckle field and texture)."""
    sensor, rng, scene = ImagingSonar(config), np.random.default_rng(seed), Scene([])
    out = []
    for _ in range(frames):
        sensor.reset()
        out.append(normalised_intensity(sensor, sensor.next_sector(scene, rng))[8::16, 4::8].ravel())
    return np.concatenate(out)


def test_empty_frames_follow_the_chosen_law_and_the_test_tells_the_laws_apart():
    # 40 frames x 256 blocks = 10240 samples per law; KS tests at a fixed seed.
    nu = 0.5
    rayleigh = decimated_samples(small(receiver_noise=False), 40, seed=1)
    k = decimated_samples(small(receiver_noise=False, clutter='k', k_shape=nu), 40, seed=2)

    def k_cdf(x):
        return 1.0 - k_sf(x, nu)

    p_exp_rayleigh = stats.kstest(rayleigh, 'expon').pvalue
    p_k_k = stats.kstest(k, k_cdf).pvalue
    p_exp_k = stats.kstest(k, 'expon').pvalue
    p_k_rayleigh = stats.kstest(rayleigh, k_cdf).pvalue
    print(f'KS p: Rayleigh vs exponential {p_exp_rayleigh:.3f}, K vs K(0.5) {p_k_k:.3f}, '
          f'K vs exponential {p_exp_k:.2e}, Rayleigh vs K(0.5) {p_k_rayleigh:.2e}')
    assert p_exp_rayleigh > 0.01 and p_k_k > 0.01
    assert p_exp_k < 1e-6 and p_k_rayleigh < 1e-6   # the test has power: each law fails the other's test


def test_k_survival_function_is_the_compound_gamma_exponential():
    rng = np.random.default_rng(3)
    nu = 0.5
    samples = rng.gamma(nu, 1 / nu, 200_000) * rng.standard_exponential(200_000)
    for x in (0.1, 1.0, 3.0, 10.0):
        assert abs(k_sf(x, nu) - np.mean(samples > x)) < 3e-3


@pytest.mark.parametrize('sidelobe_db', [UNIFORM_SIDELOBE_DB, -25.0])
def test_beam_pattern_has_its_width_and_sidelobe_level(sidelobe_db):
    width = math.radians(1.0)
    pattern = BeamPattern(width, sidelobe_db, extent=8.0)
    assert 20 * math.log10(pattern(width / 2)) == pytest.approx(-3.01, abs=0.02)
    delta = np.linspace(0.0, 8 * width, 40001)
    h2 = 20 * np.log10(np.abs(pattern(delta)) + 1e-12)
    first_null = int(np.argmax(np.diff(h2) > 0))             # where the main lobe ends
    assert h2[first_null:].max() == pytest.approx(sidelobe_db, abs=0.5)   # the peak sidelobe
    assert pattern(8.01 * width) == 0.0                       # truncated


@pytest.mark.parametrize('sidelobe_db', [UNIFORM_SIDELOBE_DB, -25.0])
def test_point_echo_spreads_across_beams_as_the_beam_pattern_says(sidelobe_db):
    # A static point 60 dB over the background on a beam and bin centre; the background is redrawn
    # every frame (reset), the echo's phase stays: the mean intensity minus the background mean is
    # the echo's |a h_b|^2 in every beam. Tolerance: 0.3 dB in the main lobe (down to -10 dB),
    # 1 dB for sidelobes down to -35 dB re the peak.
    sensor = ImagingSonar(small(receiver_noise=False, sidelobe_db=sidelobe_db))
    i, j = 128, 64
    r, b = sensor.ranges[i], sensor.bearings[j]
    scene = Scene([Target(1, StaticTrajectory(r * math.cos(b), r * math.sin(b)), shape('point'), 60.0)])
    rng = np.random.default_rng(5)
    mean = np.zeros(sensor.geometry.n_beams)
    for _ in range(40):
        sensor.reset()
        mean += normalised_intensity(sensor, sensor.next_sector(scene, rng))[i] / 40
    echo = (mean - 1.0) / (mean[j] - 1.0)
    offsets = np.arange(sensor.geometry.n_beams) - j
    delta = offsets * sensor.geometry.angle_increment
    if sidelobe_db == UNIFORM_SIDELOBE_DB:   # an unshaded line aperture: sinc^2, -3 dB at +-0.443 of its argument
        want = np.where(np.abs(delta) <= 8 * sensor.config.beam_width,
                        np.sinc(2 * 0.44295 * delta / sensor.config.beam_width) ** 2, 0.0)
    else:
        want = sensor.pattern(delta) ** 2
    main, side = want > 0.1, (want > 10 ** -3.5) & (want <= 0.1)
    err = np.abs(10 * np.log10(np.maximum(echo, 1e-12)) - 10 * np.log10(np.maximum(want, 1e-12)))
    print(f'sidelobe {sidelobe_db} dB: max error main lobe {err[main].max():.3f} dB, '
          f'sidelobes {err[side].max():.3f} dB')
    assert err[main].max() < 0.3 and err[side].max() < 1.0
    # The measured -3 dB width, interpolated across beams, is the beam width (within 5 %).
    half = np.flatnonzero(echo >= 0.5)
    lo, hi = half.min(), half.max()
    left = lo - 1 + (0.5 - echo[lo - 1]) / (echo[lo] - echo[lo - 1])
    right = hi + (echo[hi] - 0.5) / (echo[hi] - echo[hi + 1])
    width = (right - left) * sensor.geometry.angle_increment
    assert width == pytest.approx(math.radians(1.0), rel=0.05)
    # A strong echo shows sidelobe arcs: beams 1.6 deg off see it far above the background.
    assert mean[j + 6] > 100.0


@pytest.mark.parametrize('clutter', ['rayleigh', 'k'])
def test_static_scene_has_identical_speckle_frame_to_frame(clutter):
    sensor, rng = ImagingSonar(small(receiver_noise=False, clutter=clutter)), np.random.default_rng(7)
    scene = Scene([], StaticTrajectory(1.0, 2.0, 0.3))
    frames = [sensor.next_sector(scene, rng).amplitudes for _ in range(5)]
    assert all(np.array_equal(frames[0], f) for f in frames[1:])
    # Receiver noise is drawn fresh each frame.
    noisy = ImagingSonar(small(clutter=clutter, noise_db=0.0))
    a, b = noisy.next_sector(scene, rng).amplitudes, noisy.next_sector(scene, rng).amplitudes
    assert not np.array_equal(a, b)


def frame_to_frame_correlation(cells_per_frame: float, frames: int = 12, seed: int = 11) -> tuple[float, float]:
    """Measured correlation coefficient of I / L between consecutive frames of a platform turning
    ``cells_per_frame`` beam widths per frame, and the model's rho^2."""
    config = small(receiver_noise=False)
    rate = cells_per_frame * config.beam_width * config.frame_rate
    sensor, rng, scene = ImagingSonar(config), np.random.default_rng(seed), Scene([], Spinning(rate))
    intensities = [normalised_intensity(sensor, sensor.next_sector(scene, rng)).ravel() for _ in range(frames)]
    a, b = np.concatenate(intensities[:-1]), np.concatenate(intensities[1:])
    return float(np.corrcoef(a, b)[0, 1]), float(sensor.speckle_correlation(cells_per_frame)) ** 2


def test_speckle_decorrelates_with_motion_as_the_model_says():
    # A turn of d beam widths per frame moves every cell by d resolution cells: rho = exp(-(d / d0)^2),
    # d0 = 1, the intensity correlation rho^2. 11 frame pairs of 32768 cells; tolerance 0.03.
    slow, slow_model = frame_to_frame_correlation(0.5)
    fast, fast_model = frame_to_frame_correlation(1.0)
    print(f'frame-to-frame correlation: 0.5 cells/frame {slow:.3f} (model {slow_model:.3f}), '
          f'1 cell/frame {fast:.3f} (model {fast_model:.3f})')
    assert slow == pytest.approx(slow_model, abs=0.03)
    assert fast == pytest.approx(fast_model, abs=0.03)
    assert fast < slow - 0.3


def test_motion_rule_measures_displacement_in_resolution_cells():
    config = small()
    sensor = ImagingSonar(config)
    turn = sensor.motion_correlation((0.0, 0.0, 0.0), (0.0, 0.0, -0.5 * config.beam_width))
    np.testing.assert_allclose(turn, math.exp(-0.25), rtol=1e-4)
    # Moving straight ahead by one range resolution: cells on the axis move by one cell in range.
    ahead = sensor.motion_correlation((0.0, 0.0, 0.0), (config.range_resolution, 0.0, 0.0))
    axis = int(np.argmin(np.abs(sensor.bearings)))
    np.testing.assert_allclose(ahead[50:, axis], math.exp(-1.0), rtol=2e-3)


def test_strong_target_shadows_the_seabed_behind_it():
    # The vehicle (0.6 m high) broadside at 10 m, 3 m under the sonar (beyond the grazing range of
    # 8.8 m): on the seabed behind it the background drops to (L_w + g L_s) / L of its level
    # (g = -15 dB); beside it, nothing changes. 20 frames; tolerance 15 %.
    config = small(n_bins=512, range_max=15.0, receiver_noise=False)
    sensor = ImagingSonar(config)
    vehicle = Target(1, StaticTrajectory(10.0, 0.0, math.pi / 2), shape('vehicle'), 30.0)
    frames = []
    rng = np.random.default_rng(13)
    for _ in range(20):
        sensor.reset()
        frames.append(normalised_intensity(sensor, sensor.next_sector(Scene([vehicle]), rng)))
    mean = np.mean(frames, axis=0)
    behind = (sensor.ranges > 10.6) & (sensor.ranges < 11.6)
    centre = np.abs(sensor.bearings) < math.radians(5.0)
    beside = np.abs(sensor.bearings) > math.radians(14.0)
    want = float(np.mean(sensor._seabed_shadow_amp[behind] ** 2))
    shadowed = float(mean[np.ix_(behind, centre)].mean())
    print(f'shadow: {10 * math.log10(shadowed):.1f} dB (model {10 * math.log10(want):.1f} dB)')
    assert shadowed == pytest.approx(want, rel=0.15) and want < 0.2
    assert float(mean[np.ix_(behind, beside)].mean()) == pytest.approx(1.0, rel=0.1)


def test_wall_at_normal_incidence_fills_its_cells_with_its_level():
    # An arc of rough facets (normals toward the sonar) at a bin centre, rough by a wavelength (random
    # phases), 20 dB: over the 400 central beams, the mean echo at its bin re the background is 20 dB
    # within 1 dB; static and frozen, and the background behind it is shadowed.
    config = small(n_beams=512, fov_deg=130.0, receiver_noise=False)
    sensor = ImagingSonar(config)
    i = 100
    spacing = 0.02
    a = np.arange(-1.2, 1.2, spacing / sensor.ranges[i])
    u = np.stack([np.cos(a), np.sin(a)], axis=1)
    rng = np.random.default_rng(17)
    r = sensor.ranges[i] + rng.uniform(0.0, config.wavelength, len(a))
    walls = RoughShape('walls', r[:, None] * u, -u, 100.0 * spacing * rng.standard_exponential(len(a)), np.ones(len(a)),
                       2 * r.max())
    scene = Scene([], StaticTrajectory(0.0, 0.0))
    scene.structure = Structure(StructureConfig(), walls, None, Texture(np.zeros((0, 2)), np.zeros(0), 0.0))
    echo = np.abs(sensor.echo_field(scene, 0.0)[i, 56:456]) ** 2 / sensor.level[i]
    print(f'wall: {10 * math.log10(echo.mean()):.2f} dB (20 dB set)')
    assert 10 * math.log10(echo.mean()) == pytest.approx(20.0, abs=1.0)
    first, second = sensor.next_sector(scene, rng), sensor.next_sector(scene, rng)
    assert np.array_equal(first.amplitudes, second.amplitudes)
    assert np.median(normalised_intensity(sensor, first)[i + 3:]) < 0.1   # shadowed behind the wall


def reduced(scenario: str, preset: str, **flat) -> SimConfig:
    return SimConfig.for_scenario(scenario, preset, **{'imaging.n_beams': 64, 'imaging.n_bins': 200, **flat})


def test_same_seed_same_frames_other_seed_other_frames():
    cfg = reduced('imaging_harbour', 'oculus_m750d')
    runs = [Simulator(cfg, np.random.default_rng(seed)) for seed in (4, 4, 5)]
    frames = [[sim.next_sector() for _ in range(4)] for sim in runs]
    assert all(np.array_equal(a.amplitudes, b.amplitudes) and a.stamp == b.stamp and a.pose == b.pose
               for a, b in zip(frames[0], frames[1]))
    assert not np.array_equal(frames[0][3].amplitudes, frames[2][3].amplitudes)


TARGETS = {'imaging_empty': 0, 'imaging_diver': 1, 'imaging_vehicle': 1, 'imaging_school': 8, 'imaging_harbour': 1}


@pytest.mark.parametrize('preset', IMAGING_PRESETS)
@pytest.mark.parametrize('scenario', sorted(TARGETS))
def test_imaging_scenarios_run_on_every_imaging_preset(scenario, preset):
    cfg = SimConfig.for_scenario(scenario, preset)
    sim = Simulator(cfg, np.random.default_rng(1))
    assert isinstance(sim.sensor, ImagingSonar)
    g = sim.sensor.geometry
    frames = [sim.next_sector() for _ in range(3)]
    for n, f in enumerate(frames, 1):
        assert f.stamp == pytest.approx(n / cfg.imaging.frame_rate) and f.end_of_sweep
        assert f.geometry.ping_period == 0.0 and f.geometry.scan_time == pytest.approx(sim.sweep_period)
        assert f.amplitudes.shape == (cfg.imaging.n_bins, cfg.imaging.n_beams)
        assert cfg.imaging.n_beams == SENSOR_PRESETS[preset]['imaging.n_beams']
        assert f.amplitudes.dtype == np.uint8   # the presets publish 8-bit log counts
    assert len(sim.truth_records(frames[-1].stamp)) == TARGETS[scenario]
    # Every target is in the fan for most of the scenario.
    ts = np.arange(0.5, cfg.duration, 0.5)
    seen = []
    for t in ts:
        x, y, yaw, _, _ = sim.scene.platform_pose(t)
        _, states = sim.truth(t)
        d = states[:, :2] - [x, y]
        r = np.hypot(d[:, 0], d[:, 1])
        b = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - yaw)))
        seen.append((r < g.range_max) & (b > g.angle_min) & (b < g.angle_max))
    if TARGETS[scenario]:
        assert np.mean(seen) > 0.45


@pytest.mark.parametrize('preset', ['oculus_m750d', 'aris3000'])
def test_diver_spans_many_beams_at_short_range(preset):
    cfg = SimConfig.for_scenario('imaging_diver', preset)
    sim = Simulator(cfg, np.random.default_rng(2))
    ts = np.arange(0.0, cfg.duration, 0.25)
    ranges = [float(np.hypot(*sim.truth(t)[1][0, :2])) for t in ts]
    t = float(ts[int(np.argmin(ranges))])
    ratio = np.abs(sim.sensor.echo_field(sim.scene, t)) ** 2 / sim.sensor.level[:, None]
    beams = int(np.count_nonzero(ratio.max(axis=0) > 1.0))   # beams where it is over the background
    width = beams * sim.sensor.geometry.angle_increment / cfg.imaging.beam_width
    print(f'{preset}: diver at {min(ranges):.1f} m over {beams} beams ({width:.1f} beam widths); '
          f'peak {10 * math.log10(ratio.max()):.1f} dB')
    assert beams >= 10 and width >= 5.0


def test_imaging_settings_are_refused_with_a_reason():
    with pytest.raises(ConfigError, match='frame_rate'):
        SimConfig.for_scenario('imaging_diver', 'oculus_m750d', **{'imaging.range_max': 120.0})
    with pytest.raises(ConfigError, match='runs on'):
        SimConfig.for_scenario('imaging_diver', 'seaking675')
    sensor = ImagingSonar(small())
    with pytest.raises(ConfigError):
        sensor.set_clutter('weibull')


def test_clutter_law_changes_part_way():
    sensor, rng, scene = ImagingSonar(small(receiver_noise=False)), np.random.default_rng(19), Scene([])
    before = normalised_intensity(sensor, sensor.next_sector(scene, rng))
    sensor.set_clutter('k', 0.5)
    after = normalised_intensity(sensor, sensor.next_sector(scene, rng))
    # The same speckle (static platform) under a new gamma texture: blockwise ratios, heavy tail.
    ratio = (after / before)[::16, ::8]
    assert np.std(np.log(ratio)) > 1.0
    np.testing.assert_allclose(after[:16, :8] / before[:16, :8], ratio[0, 0], rtol=1e-3)
