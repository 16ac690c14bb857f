"""The ROS runtime layer: what every node of the package needs, written once.

Process set-up and ``main`` (:mod:`.runtime`), parameters from core configs (:mod:`.params`),
QoS profiles (:mod:`.qos`), the time rule (:mod:`.timeline`), the sonar pose (:mod:`.pose`),
diagnostics (:mod:`.diagnostics`), a node's state: starting, learning, ready (:mod:`.status`), the
processing-node base with guarded callbacks (:mod:`.node`),
sector input (:mod:`.sector_input`), and a simulated source's pace and stamps (:mod:`.pacing`).
Nodes in ``sonar_tracking.nodes`` only wire these to the core.
"""
from sonar_tracking.ros.coverage import CoverageSource
from sonar_tracking.ros.diagnostics import StageDiagnostics
from sonar_tracking.ros.gate import SubscriberGate
from sonar_tracking.ros.node import InputConfig, SonarNode
from sonar_tracking.ros.pacing import Pacer, PacingConfig
from sonar_tracking.ros.params import ConfigParameters, declare_choice, descriptor_for, start_value
from sonar_tracking.ros.pose import Pose, PoseConfig, PoseSource, check_sonar_pose
from sonar_tracking.ros.qos import CLOCK_TOPIC, INPUT_QOS, input_profile, latest_profile, output_profile
from sonar_tracking.ros.runtime import configure_dds, prepare_process, run_node
from sonar_tracking.ros.sector_input import SectorInput, SectorInputConfig
from sonar_tracking.ros.status import LEARNING, READY, STARTING, NodeStatus, StatusWatch, warmup_left
from sonar_tracking.ros.timeline import LATE, NEW, RESET, TimeGuard
from sonar_tracking.ros.track_output import TrackOutput, TrackOutputConfig

__all__ = [
    'StageDiagnostics', 'InputConfig', 'SonarNode', 'ConfigParameters', 'descriptor_for', 'start_value',
    'declare_choice', 'Pacer', 'PacingConfig',
    'Pose', 'PoseConfig', 'PoseSource', 'check_sonar_pose', 'CLOCK_TOPIC', 'INPUT_QOS', 'input_profile',
    'latest_profile', 'output_profile', 'configure_dds', 'prepare_process', 'run_node', 'SectorInput',
    'SectorInputConfig', 'LATE', 'NEW', 'RESET', 'TimeGuard', 'SubscriberGate',
    'TrackOutput', 'TrackOutputConfig', 'CoverageSource', 'STARTING', 'LEARNING', 'READY', 'NodeStatus',
    'StatusWatch', 'warmup_left',
]
