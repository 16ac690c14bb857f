"""``sonar_import --picture``: no-data pixels in a colour outside the colour map, a colour bar with units,
forward up, a title with the time span, and seven track trails that stay readable."""
from __future__ import annotations

import math
from datetime import datetime, timezone

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.cli import import_picture
from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.core.records import GPF_TRACK_DTYPE, REGION_DTYPE
from sonar_tracking.msgs.map_info import grid_to_map_info

T0 = int(datetime(2024, 5, 6, 10, 15, 12, tzinfo=timezone.utc).timestamp()) * 10**9
SONAR = (5.0, 5.0, 0.6)                # the sonar faces 34 deg left of +x of the world
N_TRACKS, N_POINTS = 7, 400


def odometry(types, ns):
    x, y, yaw = SONAR
    new = types.new
    pose = new('geometry_msgs/msg/Pose', position=new('geometry_msgs/msg/Point', x=x, y=y, z=0.0),
               orientation=new('geometry_msgs/msg/Quaternion', x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))
    header = new('std_msgs/msg/Header', stamp=new('builtin_interfaces/msg/Time', sec=ns // 10**9, nanosec=ns % 10**9),
                 frame_id='world')
    return new('nav_msgs/msg/Odometry', header=header, child_frame_id='sonar',
               pose=new('geometry_msgs/msg/PoseWithCovariance', pose=pose))


@pytest.fixture(scope='module')
def run_bag(tmp_path_factory):
    """A run as a stack records it: FLS images (data in the upper half of the grid, none below, a
    strong echo at (10, 12)), regions, odometry, and seven tracks of 400 positions each that cross."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    types = ma.RosbagsTypes(ts)
    path = tmp_path_factory.mktemp('picture') / 'run'
    w = Writer(path, version=8)
    w.open()
    conns = {}

    def write(topic, msgtype, msg, ns):
        if topic not in conns:
            conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
        w.write(conns[topic], ns, ts.serialize_cdr(msg, msgtype))
    grid = ImageGrid(resolution=0.1, width=200, height=200, origin_x=0.0, origin_y=0.0)
    image = np.zeros(grid.shape, np.float32)
    rows, cols = np.indices(grid.shape)
    _, y = grid.pixel_to_point(rows, cols)
    image[y >= 10.0] = 1.0                        # background level where there is data, 0 (no data) elsewhere
    r, c = (int(round(float(v))) for v in grid.point_to_pixel(10.0, 12.0))
    image[r - 3:r + 4, c - 3:c + 4] = 100.0       # 20 dB: the strongest echo
    for k in range(N_POINTS):
        ns = T0 + k * 10**8                       # 0.1 s apart: 39.9 s in all
        if k % 100 == 99:
            write('/fls/image', 'sensor_msgs/msg/Image', ma.array_to_image(image, stamp_ns=ns, frame_id='world',
                                                                           types=types), ns)
            write('/fls/image_info', 'nav_msgs/msg/MapMetaData', grid_to_map_info(grid, ns, types), ns)
            regions = np.zeros(1, REGION_DTYPE)
            regions['x'], regions['y'] = 10.0, 12.0
            write('/fls/regions', 'sensor_msgs/msg/PointCloud2', ma.array_to_cloud(regions, stamp_ns=ns, types=types),
                  ns)
        tracks = np.zeros(N_TRACKS, GPF_TRACK_DTYPE)
        tracks['track_id'] = np.arange(1, N_TRACKS + 1)
        f = k / (N_POINTS - 1)
        tracks['x'] = 2.0 + 16.0 * f                                  # all cross the picture, fanning out
        tracks['y'] = 10.0 + np.arange(N_TRACKS) * 1.2 * f + 0.3 * np.sin(k / 7.0)
        write('/gpf/tracks', 'sensor_msgs/msg/PointCloud2', ma.array_to_cloud(tracks, stamp_ns=ns, types=types), ns)
        if k % 10 == 0:
            write('/platform/odometry', 'nav_msgs/msg/Odometry', odometry(types, ns), ns)
    w.close()
    return path


def pixel(picture, x, y):
    """The saved picture's (row, column) of the point (x, y) of the records' frame."""
    h, v = picture.view(x, y)
    px, py = picture.ax.transData.transform((float(h), float(v)))
    height = picture.fig.canvas.get_width_height()[1]
    return int(round(height - py)), int(round(px))


def test_no_data_pixels_have_a_colour_outside_the_colour_map(run_bag, tmp_path):
    import matplotlib.image
    import matplotlib.pyplot as plt
    picture = import_picture.render_run(run_bag)
    png = tmp_path / 'run.png'
    picture.fig.savefig(png)
    rgb = matplotlib.image.imread(png)[..., :3]
    colours = plt.get_cmap(import_picture.COLOUR_MAP)(np.linspace(0.0, 1.0, 256))[:, :3]

    def nearest_in_map(colour):
        return float(np.min(np.linalg.norm(colours - colour, axis=1)))
    no_data = rgb[pixel(picture, 10.0, 5.0)]          # inside the image, where it holds no data
    strong = rgb[pixel(picture, 10.0, 12.0)]          # the strongest echo
    background = rgb[pixel(picture, 16.0, 19.0)]      # data at the background level
    assert nearest_in_map(no_data) > 0.2                                       # not a colour of the map
    assert np.allclose(no_data, import_picture.NO_DATA, atol=0.01)
    assert picture.ax.get_facecolor()[:3] == pytest.approx(import_picture.NO_DATA)   # beyond the image too
    assert np.allclose(strong, colours[-1], atol=0.02)                         # the top of the map
    assert nearest_in_map(background) < 0.02 and np.linalg.norm(background - no_data) > 0.2
    labels = [t.get_text() for t in picture.fig.legends[0].get_texts()]
    assert 'no data' in labels
    colour_bar = [a for a in picture.fig.axes if a is not picture.ax]
    assert len(colour_bar) == 1 and 'dB' in colour_bar[0].get_ylabel()
    title = picture.ax.get_title()
    assert title.startswith('run: 2024-05-06 10:15:12 to 2024-05-06 10:15:51 UTC (39.9 s)'), title
    plt.close(picture.fig)


def test_forward_up_and_seven_readable_tracks(run_bag):
    import matplotlib.pyplot as plt
    picture = import_picture.render_run(run_bag)
    x, y, yaw = SONAR
    sonar = pixel(picture, x, y)
    ahead = pixel(picture, x + 5 * math.cos(yaw), y + 5 * math.sin(yaw))
    port = pixel(picture, x - 5 * math.sin(yaw), y + 5 * math.cos(yaw))
    assert ahead[0] < sonar[0] - 20 and abs(ahead[1] - sonar[1]) <= 1       # ahead is up
    assert port[1] < sonar[1] - 20 and abs(port[0] - sonar[0]) <= 1          # port is left
    lines = [ln for ln in picture.ax.get_lines() if ln.get_label().startswith('/gpf/tracks')]
    assert [ln.get_label() for ln in lines] == [f'/gpf/tracks {k}' for k in range(1, N_TRACKS + 1)]
    assert len({ln.get_color() for ln in lines}) == N_TRACKS and 'grey' not in {ln.get_color() for ln in lines}
    for k, ln in enumerate(lines):
        h, v = ln.get_data()
        assert 10 <= len(h) <= 80 < N_POINTS                                   # thinned
        first = picture.view(2.0, 10.0)                                      # kept: the first and last positions
        last = picture.view(18.0, 10.0 + 1.2 * k + 0.3 * math.sin((N_POINTS - 1) / 7.0))
        assert (h[0], v[0]) == pytest.approx(tuple(map(float, first)))
        assert (h[-1], v[-1]) == pytest.approx(tuple(map(float, last)))
    ids = {t.get_text() for t in picture.ax.texts}
    assert ids == {str(k) for k in range(1, N_TRACKS + 1)}
    assert picture.drawn == {'image': 1, 'regions': 1, 'gpf_tracks': N_TRACKS, 'tracks': 0, 'detections': 0,
                             'poses': N_POINTS // 10}
    plt.close(picture.fig)
