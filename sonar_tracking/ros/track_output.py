"""Track output of both trackers: the record topic and its RViz markers, confirmed tracks by default.

``TrackOutputConfig`` declares what people and tools see (``publish_tentative``,
``markers_tentative``, ``marker_scale``); :class:`TrackOutput` publishes one tracker step: the
records (``TRACK_DTYPE`` / ``GPF_TRACK_DTYPE``, width 0 when there are none) on ``topic`` and a
MarkerArray (DELETEALL, then sphere, label, velocity arrow and covariance ellipse per track) on
``topic/markers``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import Config, setting
from sonar_tracking.ros.qos import output_profile

__all__ = ['TrackOutputConfig', 'TrackOutput']


@dataclass(frozen=True)
class TrackOutputConfig(Config):
    """What a tracker publishes."""

    publish_tentative: bool = setting(False, 'publish tentative tracks too (field confirmed = 0); default: '
                                      'confirmed tracks only')
    markers_tentative: bool = setting(False, 'draw tentative tracks in the markers as well')
    marker_scale: float = setting(1.0, 'diameter of a track sphere in the markers', unit='m', low=0.0, high=1e5,
                                  low_open=True)


class TrackOutput:
    """Publishes a tracker's records on ``topic`` and markers (namespace ``ns``) on ``topic/markers``."""

    def __init__(self, node, topic: str, ns: str) -> None:
        self.ns = ns
        self.pub_tracks = node.create_publisher(PointCloud2, topic, output_profile())
        self.pub_markers = node.create_publisher(MarkerArray, topic + '/markers', output_profile(10))

    def publish(self, tracks: np.ndarray, stamp_ns: int, frame_id: str, config: TrackOutputConfig) -> None:
        confirmed = tracks[tracks['confirmed'] != 0]
        out = tracks if config.publish_tentative else confirmed
        self.pub_tracks.publish(ma.array_to_cloud(out, stamp_ns=stamp_ns, frame_id=frame_id))
        shown = tracks if config.markers_tentative else confirmed
        self.pub_markers.publish(ma.track_markers(shown, stamp_ns=stamp_ns, frame_id=frame_id, ns=self.ns,
                                                  scale=config.marker_scale))
