"""Scanning-sonar simulator: scenes, target motion and shapes, harbour and SeaKing sensor models,
static structure and the 8-bit output coding."""
from .amplitude import AmplitudeConfig, AmplitudeModel, exponential_pd, exponential_pfa, snr_linear
from .harbour import HarbourConfig, HarbourSonar
from .presets import SCENARIOS, SENSOR_PRESETS, build_scene, scenario_info
from .scene import ClutterRegion, Scene, Target
from .seaking import SeaKingConfig, SeaKingSonar
from .sensor import SimSector
from .simulator import SimConfig, Simulator, describe
from .structure import OutputConfig, StructureConfig

__all__ = ['AmplitudeConfig', 'AmplitudeModel', 'exponential_pd', 'exponential_pfa', 'snr_linear',
           'HarbourConfig', 'HarbourSonar', 'SCENARIOS', 'SENSOR_PRESETS', 'build_scene', 'scenario_info',
           'ClutterRegion', 'Scene', 'Target', 'SeaKingConfig', 'SeaKingSonar', 'SimSector', 'SimConfig',
           'Simulator', 'describe', 'OutputConfig', 'StructureConfig']
