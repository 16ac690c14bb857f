"""Sonar simulator: scenes, target motion and shapes, the harbour, SeaKing and multibeam imaging sensor
models, static structure and the 8-bit output coding."""
from sonar_tracking.sim.amplitude import AmplitudeConfig, AmplitudeModel, exponential_pd, exponential_pfa, snr_linear
from sonar_tracking.sim.harbour import HarbourConfig, HarbourSonar
from sonar_tracking.sim.imaging import ImagingConfig, ImagingSonar
from sonar_tracking.sim.presets import IMAGING_PRESETS, SCENARIOS, SENSOR_PRESETS, build_scene, scenario_info
from sonar_tracking.sim.scene import ClutterRegion, Scene, Target
from sonar_tracking.sim.seaking import SeaKingConfig, SeaKingSonar
from sonar_tracking.sim.sensor import SimSector
from sonar_tracking.sim.simulator import SimConfig, Simulator, describe
from sonar_tracking.sim.structure import OutputConfig, StructureConfig

__all__ = ['AmplitudeConfig', 'AmplitudeModel', 'exponential_pd', 'exponential_pfa', 'snr_linear',
           'HarbourConfig', 'HarbourSonar', 'ImagingConfig', 'ImagingSonar', 'IMAGING_PRESETS', 'SCENARIOS',
           'SENSOR_PRESETS', 'build_scene', 'scenario_info',
           'ClutterRegion', 'Scene', 'Target', 'SeaKingConfig', 'SeaKingSonar', 'SimSector', 'SimConfig',
           'Simulator', 'describe', 'OutputConfig', 'StructureConfig']
