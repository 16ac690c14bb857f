"""``projected_sonar_adapter``: a live imaging sonar's ``marine_acoustic_msgs/ProjectedSonarImage`` as sectors.

Subscribes ``sonar_image`` (remap it to the driver's topic, e.g. ``/oculus/sonar_image``; QoS from
``input_qos``: drivers usually publish best effort, so ``sensor_data``) and publishes each message as
one sector, ``sonar/sector`` + ``sonar/sector_info`` with the message's stamp: the same conversion
as ``sonar_import`` (:func:`sonar_tracking.io.importers.projected_to_sector`: beams sorted into
increasing REP-103 bearing and resampled onto an even grid, the message's z-forward frame
converted) and the same intensity handling (:func:`~sonar_tracking.io.importers.condition_sector`).

``marine_acoustic_msgs`` is not among the ROS wheels. Where it is not importable the node has no
possible input: it says so and how to build it, and exits with status :data:`EXIT_NO_INTERFACES`.
With ``wait_for_interfaces: true`` it stays up instead, reports ``waiting for marine_acoustic_msgs``
in ``diagnostics`` and tries the import again every :data:`RETRY_PERIOD` seconds, so a package
built meanwhile into a prefix already on ``PYTHONPATH`` (a sourced workspace) is picked up. Bad
messages (sizes that disagree, an unknown dtype, a late stamp) are dropped with a logged reason.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from sensor_msgs.msg import Image, LaserScan

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.sector import GeometryError
from sonar_tracking.io.importers import ProjectedOptions, condition_sector, projected_to_sector
from sonar_tracking.ros import InputConfig, SonarNode, output_profile, run_node

__all__ = ['AdapterConfig', 'ProjectedSonarAdapter', 'convert', 'main', 'EXIT_NO_INTERFACES']

BUILD_HINT = 'python -m sonar_tracking.cli.build_interfaces'
#: Exit status without ``marine_acoustic_msgs`` (and without ``wait_for_interfaces``).
EXIT_NO_INTERFACES = 3
#: Seconds between import attempts while waiting for ``marine_acoustic_msgs``.
RETRY_PERIOD = 2.0


@dataclass(frozen=True)
class AdapterConfig(ProjectedOptions, InputConfig):
    """The importer's imaging-sonar settings plus input QoS, the time rule, and what to do without
    the message package."""

    wait_for_interfaces: bool = setting(False, 'without marine_acoustic_msgs, stay up and retry the import '
                                        f'every {RETRY_PERIOD:g} s (default: exit with status {EXIT_NO_INTERFACES})',
                                        read_only=True)


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
        self.sub = None
        self.retry = None
        if self._try_subscribe():
            return
        missing = f'marine_acoustic_msgs is not importable, so there is no input; build it with `{BUILD_HINT}`'
        if not self.config.wait_for_interfaces:
            self.get_logger().error(f'{missing} and source install/setup.bash; exiting (or start with '
                                    '-p wait_for_interfaces:=true to wait for it)')
            raise SystemExit(EXIT_NO_INTERFACES)
        self.get_logger().warning(f'{missing}; waiting for it (retrying the import every {RETRY_PERIOD:g} s)')
        self.retry = self.create_timer(RETRY_PERIOD, self._retry)

    def _try_subscribe(self) -> bool:
        """Subscribe ``sonar_image`` if ``marine_acoustic_msgs`` imports; whether it did."""
        importlib.invalidate_caches()   # a package built since the last attempt
        try:
            from marine_acoustic_msgs.msg import ProjectedSonarImage
        except ImportError:
            return False
        self.sub = self.subscribe(ProjectedSonarImage, 'sonar_image', self.on_image, self.input_qos())
        c = self.config
        self.get_logger().info(f'sonar_image -> sonar/sector: beam frame {c.beam_frame}, layout {c.image_layout}, '
                               f'{"decoded " + c.intensity.coding if c.decode else "values kept"}')
        return True

    def _retry(self) -> None:
        if self._try_subscribe() and self.retry is not None:
            self.destroy_timer(self.retry)
            self.retry = None

    def status_values(self) -> dict[str, str]:
        return {'input': 'sonar_image' if self.sub is not None else 'waiting for marine_acoustic_msgs'}

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
