"""``sonar_import``'s per-message work: a Ping360 turn through the sweep assembler, and an uneven
512-beam ProjectedSonarImage (Oculus M750d-class) onto the even bearing grid.

Inputs: 400 pings of 1200 uint8 samples at 1 grad steps (one full turn, one sector); a 512-beam x
1000-bin uint8 image with beams spaced as the arcsine of an even grid over +-65 deg.
"""
from __future__ import annotations

import math

import numpy as np

from sonar_tracking.cli.bench import Case, register


def _turn():
    from sonar_tracking.io.importers import Ping, SweepAssembler
    rng = np.random.default_rng(3)
    samples = rng.integers(0, 255, (401, 1200)).astype(np.uint8)
    bearings = np.remainder(np.arange(401) * math.pi / 200 + math.pi, 2 * math.pi) - math.pi

    def run():
        asm = SweepAssembler()
        out = []
        for k in range(401):  # the 401st ping closes the turn
            out += asm.add(Ping(k * 20_000_000, k * 20_000_000, float(bearings[k]), samples[k], 0.01, 20.0))
        return out
    return run


def _projected():
    from rosbags.typesys import Stores, get_typestore

    from sonar_tracking.io.importers import ImportOptions, projected_to_sector
    from sonar_tracking.io.importers.msgdefs import register_builtin
    from sonar_tracking.msgs import RosbagsTypes
    store = get_typestore(Stores.ROS2_JAZZY)
    register_builtin(store)
    t = RosbagsTypes(store)
    az = np.arcsin(np.linspace(-1, 1, 512) * math.sin(math.radians(65)))
    dirs = [t.new('geometry_msgs/msg/Vector3', x=0.0, y=-math.sin(a), z=math.cos(a)) for a in az]
    data = np.random.default_rng(4).integers(0, 255, 512 * 1000).astype(np.uint8)
    msg = t.new('marine_acoustic_msgs/msg/ProjectedSonarImage', beam_directions=dirs,
                ranges=((np.arange(1000) + 0.5) * 0.02).astype(np.float32),
                image=t.new('marine_acoustic_msgs/msg/SonarImageData', dtype=0, beam_count=512, data=data))
    options = ImportOptions()
    return lambda: projected_to_sector(msg, options)


register(Case(name='importers.ping360_turn', group='importers', make=_turn,
              description='400 Ping360 pings (1200 samples) grouped into one 360 deg sector', repeats=10))
register(Case(name='importers.projected_512_beams', group='importers', make=_projected,
              description='uneven 512-beam x 1000-bin ProjectedSonarImage resampled onto the even grid', repeats=10))
