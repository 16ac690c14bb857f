"""``fls_features``: FLS image building, modified median filter, region growing, region features.

Subscribes ``sonar/sector`` + ``sonar/sector_info`` (paired by stamp; a half that never finds its
partner is dropped with a warning) and ``platform/odometry`` (the sonar's pose for a moving
platform; without it the ``sonar_pose`` parameter). Publishes, whenever a sweep completes (or
every sector with ``image.publish: sector``), in this order and with one stamp (the last sector
in the image):

* ``fls/image_info`` (``nav_msgs/MapMetaData``): the pixel <-> metres mapping of the image,
  ``map_load_time`` = the image stamp (see ``sonar_tracking.msgs.map_info``);
* ``fls/image`` (``sensor_msgs/Image`` ``32FC1``): the processed image the regions refer to:
  filtered, range-normalised intensity (1 = background level, 0 = no data), in OccupancyGrid
  layout (columns along x, rows along y of ``header.frame_id``);
* ``fls/regions`` (``sensor_msgs/PointCloud2``, REGION_DTYPE): one point per region, ``x, y`` in
  the image's frame, ``range, bearing`` from the sonar, features ``f01..f30`` (Table 2); width 0
  when there are none;

``diagnostics`` once a second, and ``~/status`` (starting, learning while the structure
background holds regions back, ready: :mod:`sonar_tracking.ros.status`). ``frame: world``
(default) places sectors by their pose in ``world_frame``; ``frame: sensor`` paints them in the
sonar's own frame (a static sonar).

Bad input (unknown encoding, image and geometry that disagree, an empty, all-zero or non-finite
sector, a late stamp) is logged and the message dropped; the node keeps running. A jump back in
time restarts the image (a new recording; :mod:`sonar_tracking.ros.timeline`).
"""
from __future__ import annotations

import time
from collections import OrderedDict
from dataclasses import dataclass

from nav_msgs.msg import MapMetaData
from sensor_msgs.msg import Image, PointCloud2

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.fls import FlsConfig, FlsFrame, FlsInputError, FlsProcessor
from sonar_tracking.msgs.map_info import grid_to_map_info
from sonar_tracking.ros import SectorInput, SectorInputConfig, SonarNode, output_profile, run_node, warmup_left

__all__ = ['FlsNodeConfig', 'FlsFeaturesNode', 'main']


@dataclass(frozen=True)
class FlsNodeConfig(FlsConfig, SectorInputConfig):
    """FLS front-end settings plus the node's frames, static pose and timing."""

    frame: str = setting('world', 'frame of the image and regions: world (sectors placed by odometry or '
                         'sonar_pose) or sensor (the sonar frame, a static sonar)', choices=('world', 'sensor'),
                         read_only=True)
    world_frame: str = setting('world', 'name of the world frame (frame_id of the outputs when frame = world)',
                               read_only=True)


class FlsFeaturesNode(SonarNode):
    """Runs an :class:`FlsProcessor` on paired sectors and publishes its frames."""

    #: Start-up only here, beyond the settings declared read-only (the image grid is built once).
    READ_ONLY = {'image.resolution'}

    def __init__(self, **kwargs) -> None:
        mutable = {s.name for s in FlsNodeConfig.settings() if not s.read_only} - self.READ_ONLY
        super().__init__('fls_features', FlsNodeConfig(), 'fls_features: segmentation', mutable=mutable, **kwargs)
        self.processor = FlsProcessor(self.config)
        self._ns_of: OrderedDict[float, int] = OrderedDict()
        self._t0_ns: int | None = None
        self._t: float | None = None     # the last sector's time on the processor's clock [s]
        self.frames = 0
        self.watch_warmup(lambda: warmup_left(self.processor.warmup, self.processor.config.structure, self._t))
        self.input = SectorInput(self, self._process, self._on_reset, use_odometry=lambda: self.config.frame == 'world')
        out = output_profile(50)
        self.pub_info = self.create_publisher(MapMetaData, 'fls/image_info', out)
        self.pub_image = self.create_publisher(Image, 'fls/image', out)
        self.pub_regions = self.create_publisher(PointCloud2, 'fls/regions', out)
        c = self.config
        self.get_logger().info(
            f'{c.image.resolution:g} m pixels in the {c.frame} frame, published per {c.image.publish}; filter '
            f'{c.filter.window_bins} bins x {c.filter.window_beams} beams trim {c.filter.trim}; regions from '
            f'{c.segment.seed_db:g} dB, grown to {c.segment.grow_db:g} dB, joined within {c.segment.join_distance:g} m')

    def on_change(self, old: FlsNodeConfig, new: FlsNodeConfig) -> None:
        self.processor.reconfigure(new)
        if new.filter != old.filter:
            self.get_logger().info('filter settings changed: the image starts again')

    # -- processing --------------------------------------------------------------------------
    def _on_reset(self) -> None:
        self.processor.reset()
        self._t0_ns = self._t = None

    def _process(self, stamp_ns: int, amplitudes, geometry, pose, frame_id: str) -> bool:
        started = time.perf_counter()
        if self._t0_ns is None:
            self._t0_ns = stamp_ns
        t = (stamp_ns - self._t0_ns) / 1e9  # seconds since the first sector: exact enough as a float
        try:
            frames = self.processor.add_sector(amplitudes, geometry, pose, t)
        except FlsInputError as exc:
            self.say('error', f'sector at {stamp_ns / 1e9:.3f} s dropped: {exc}', 'bad_values')
            return False
        self._ns_of[t] = stamp_ns
        self._t = t
        while len(self._ns_of) > 256:
            self._ns_of.popitem(last=False)
        self._frame_id = self.config.world_frame if self.config.frame == 'world' else (frame_id or 'sonar')
        for frame in frames:
            self._publish(frame)
        self.diag.done(started)
        return True

    def _publish(self, frame: FlsFrame) -> None:
        stamp_ns = self._ns_of.get(frame.stamp, self._t0_ns + int(round(frame.stamp * 1e9)))
        self.pub_info.publish(grid_to_map_info(frame.grid, stamp_ns))
        self.pub_image.publish(ma.array_to_image(frame.image, '32FC1', stamp_ns=stamp_ns, frame_id=self._frame_id))
        self.pub_regions.publish(ma.array_to_cloud(frame.regions, stamp_ns=stamp_ns, frame_id=self._frame_id))
        self.frames += 1
        self.diag.values = {
            'frames': str(self.frames), 'regions': str(len(frame.regions)), 'structure': str(frame.structure),
            'image': f'{frame.grid.width} x {frame.grid.height} px at {frame.grid.resolution:g} m',
            'sectors_in_frame': str(frame.sectors), 'background_db': f'{frame.background_db:.2f}',
            'odometry': 'yes' if self.input.has_odometry else 'no (sonar_pose)',
        } | {f'{k}_ms': f'{1e3 * v:.2f}' for k, v in frame.timings.items()}


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking fls_features``."""
    return run_node(FlsFeaturesNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
