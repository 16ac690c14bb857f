"""The ROS runtime layer: what every node of the package needs, written once.

Process set-up and ``main`` (:mod:`.runtime`), parameters from core configs (:mod:`.params`),
QoS profiles (:mod:`.qos`), the time rule (:mod:`.timeline`), the sonar pose (:mod:`.pose`),
diagnostics (:mod:`.diagnostics`), the processing-node base with guarded callbacks (:mod:`.node`),
sector input (:mod:`.sector_input`), and a simulated source's pace and stamps (:mod:`.pacing`).
Nodes in ``sonar_tracking.nodes`` only wire these to the core.
"""
from .coverage import CoverageSource
from .diagnostics import StageDiagnostics
from .gate import SubscriberGate
from .node import InputConfig, SonarNode
from .params import ConfigParameters, declare_choice, descriptor_for, start_value
from .pacing import Pacer, PacingConfig
from .pose import Pose, PoseConfig, PoseSource, check_sonar_pose
from .qos import CLOCK_TOPIC, INPUT_QOS, input_profile, latest_profile, output_profile
from .runtime import configure_dds, prepare_process, run_node
from .sector_input import SectorInput, SectorInputConfig
from .timeline import LATE, NEW, RESET, TimeGuard
from .track_output import TrackOutput, TrackOutputConfig

__all__ = [
    'StageDiagnostics', 'InputConfig', 'SonarNode', 'ConfigParameters', 'descriptor_for', 'start_value',
    'declare_choice', 'Pacer', 'PacingConfig',
    'Pose', 'PoseConfig', 'PoseSource', 'check_sonar_pose', 'CLOCK_TOPIC', 'INPUT_QOS', 'input_profile',
    'latest_profile', 'output_profile', 'configure_dds', 'prepare_process', 'run_node', 'SectorInput',
    'SectorInputConfig', 'LATE', 'NEW', 'RESET', 'TimeGuard', 'SubscriberGate',
    'TrackOutput', 'TrackOutputConfig', 'CoverageSource',
]
