"""``projected_sonar_adapter``: a live imaging sonar's ``marine_acoustic_msgs/ProjectedSonarImage`` as sectors.

Subscribes ``sonar_image`` (remap it to the driver's topic, e.g. ``/oculus/sonar_image``; QoS from
``input_qos``: drivers usually publish best effort, so ``sensor_data``) and publishes each message as
one sector, ``sonar/sector`` + ``sonar/sector_info`` with the message's stamp: the same conversion
as ``sonar_import`` (:func:`sonar_tracking.io.importers.projected_to_sector`: beams sorted into
increasing REP-103 bearing and resampled onto an even grid, the message's z-forward frame
converted) and the same intensity handling (:func:`~sonar_tracking.io.importers.condition_sector`).

``marine_acoustic_msgs`` is not among the ROS wheels; where it is not importable the node still
starts, says so and how to build it, and reports it in ``diagnostics``. Bad messages (sizes that
disagree, an unknown dtype, a late stamp) are dropped with a logged reason.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sensor_msgs.msg import Image, LaserScan

import sonar_tracking.msgs as ma
from sonar_tracking.core.sector import GeometryError
from sonar_tracking.io.importers import ProjectedOptions, condition_sector, projected_to_sector
from sonar_tracking.ros import InputConfig, SonarNode, output_profile, run_node

__all__ = ['AdapterConfig', 'ProjectedSonarAdapter', 'convert', 'main']

BUILD_HINT = 'python -m sonar_tracking.cli.build_interfaces'


@dataclass(frozen=True)
class AdapterConfig(ProjectedOptions, InputConfig):
    """The importer's imaging-sonar settings plus input QoS and the time rule."""


def convert(msg: Any, config: ProjectedOptions, scan_time: float = 0.0) -> tuple[Any, Any, int]:
    """The sector Image and LaserScan (rclpy) of a ProjectedSonarImage (rclpy or rosbags), and the
    number of negative values set to 0. Raises ValueError for a malformed message."""
    values, geometry, negatives = projected_to_sector(msg, config, scan_time)
    values, geometry = condition_sector(values, geometry, config)
    stamp = ma.header_ns(msg)
    frame_id = config.frame_id or str(msg.header.frame_id)
    image = ma.array_to_image(values, stamp_ns=stamp, frame_id=frame_id)
    scan = ma.geometry_to_scan(geometry, amplitudes=values, stamp_ns=stamp, frame_id=frame_id)
    return image, scan, negatives


class ProjectedSonarAdapter(SonarNode):
    """ProjectedSonarImage in, sector pair out (module docstring)."""

    def __init__(self, **kwargs) -> None:
        super().__init__('projected_sonar_adapter', AdapterConfig(), 'projected_sonar_adapter: conversion', **kwargs)
        out = output_profile(50)
        self.pub_image = self.create_publisher(Image, 'sonar/sector', out)
        self.pub_info = self.create_publisher(LaserScan, 'sonar/sector_info', out)
        self.last_ns = 0
        self.sectors = 0
        try:
            from marine_acoustic_msgs.msg import ProjectedSonarImage
        except ImportError:
            self.sub = None
            self.say('error', f'marine_acoustic_msgs is not importable, so there is no input; build it with '
                              f'`{BUILD_HINT}` and source install/setup.bash', reason='no_message_package')
            return
        self.sub = self.subscribe(ProjectedSonarImage, 'sonar_image', self.on_image, self.input_qos())
        c = self.config
        self.get_logger().info(f'sonar_image -> sonar/sector: beam frame {c.beam_frame}, layout {c.image_layout}, '
                               f'{"decoded " + c.intensity.coding if c.decode else "values kept"}')

    def on_image(self, msg: Any) -> None:
        """Convert and publish one ProjectedSonarImage (dropped with a reason if it is malformed)."""
        stamp = ma.header_ns(msg)
        if not self.admit(stamp, 'sonar image', self._reset):
            return
        scan_time = (stamp - self.last_ns) / 1e9 if 0 < self.last_ns < stamp else 0.0
        try:
            image, scan, negatives = convert(msg, self.config, scan_time)
        except (ValueError, GeometryError, ma.AdapterError) as exc:
            self.say('warning', f'sonar image at {stamp / 1e9:.6f} s dropped: {exc}', reason='bad_image')
            return
        if negatives:
            self.say('warning', f'sonar image at {stamp / 1e9:.6f} s: {negatives} negative values set to 0')
        self.last_ns = stamp
        self.time.accept(stamp)
        self.pub_image.publish(image)
        self.pub_info.publish(scan)
        self.sectors += 1

    def _reset(self, last_ns: int) -> None:
        self.last_ns = 0


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking projected_sonar_adapter``."""
    return run_node(ProjectedSonarAdapter, args)


if __name__ == '__main__':
    raise SystemExit(main())
