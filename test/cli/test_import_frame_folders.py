"""Folders of exported frames: the README's steps for your own recordings, run as written on a folder
of polar frames with an uneven angle table and on a folder of Cartesian fan images, with the
README's own ``sonar.yaml`` examples. Each folder holds one bright point target; it must come out
within one resolution cell of where it was, in the sector (bearing within one beam, range within
one bin) and through the FLS front end (world position within one cell).

Steps 1 and 2 (``sonar_import``) run as the README writes them, with ``REC`` the folder and
``SENSOR`` the ARIS/DIDSON preset; steps 3 to 5 start a stack and a replay, which the FLS front
end's core stands in for here (``test_sonar_import.py`` runs an imported bag through the node).
"""
from __future__ import annotations

import math
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
import yaml

import sonar_tracking.msgs as ma
from sonar_tracking.cli.sonar_import import main as sonar_import
from sonar_tracking.core.fls import FlsProcessor
from sonar_tracking.io.bags import read_bag

ROOT = Path(__file__).resolve().parents[2]
T0 = 1_714_990_512.0                    # 2024-05-06 10:15:12 UTC
TARGET_RANGE = 6.0                      # m: the polar target's range (its bearing is chosen on the table)
N_FRAMES = 3


def readme_section() -> str:
    text = (ROOT / 'README.md').read_text()
    return text.split('## Your own recordings', 1)[1].split('\n## ', 1)[0]


def readme_steps() -> list[list[str]]:
    """The sonar_import command lines of the README's steps (without --picture, which needs a run)."""
    block = re.search(r'```bash\n(.*?)```', readme_section(), re.S).group(1)
    steps = [shlex.split(line.split('#', 1)[0]) for line in block.splitlines() if line.startswith('sonar_import')]
    return [s for s in steps if '--picture' not in s]


def readme_yaml(kind: str) -> dict:
    blocks = [yaml.safe_load(b) for b in re.findall(r'```yaml\n(.*?)```', readme_section(), re.S)]
    return next(b for b in blocks if (b.get('image') == 'fan') == (kind == 'fan'))


def run_readme_steps(folder: Path, cwd: Path, monkeypatch, capsys) -> tuple[str, str]:
    """Steps 1 and 2 as written (REC = the folder, SENSOR = aris_didson); their outputs."""
    monkeypatch.chdir(cwd)
    outputs = []
    for step in readme_steps():
        args = [str(folder) if a == 'REC' else 'aris_didson' if a == 'SENSOR' else a for a in step[1:]]
        code = sonar_import(args)
        out = capsys.readouterr()
        assert code == 0, f'{shlex.join(step)}: exit {code}\n{out.err}'
        outputs.append(out.out + out.err)
    return outputs[0], outputs[1]


def read_sectors(bag: Path):
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    pairer, sectors = ma.SectorPairer(), []
    for m in read_bag(bag):
        msgtype = {'/sonar/sector': 'sensor_msgs/msg/Image', '/sonar/sector_info': 'sensor_msgs/msg/LaserScan'}[m.topic]
        msg = ts.deserialize_cdr(m.data, msgtype)
        pair = pairer.add_image(msg) if m.topic == '/sonar/sector' else pairer.add_info(msg)
        if pair is not None:
            sectors.append((*ma.sector_from_messages(pair.image, pair.info), pair.stamp_ns))
    return sectors


def fls_config():
    """The FLS front end as the ARIS/DIDSON preset configures ``fls_features`` (its decoding of the
    kept counts included), without structure rejection, which needs seconds of frames to learn."""
    from sonar_tracking.io import param_files
    from sonar_tracking.nodes.fls_features import FlsNodeConfig
    params = param_files.parameters_for(param_files.load(ROOT / 'config' / 'sensors' / 'aris_didson.yaml'),
                                        'fls_features')
    return FlsNodeConfig.from_flat({**params, 'structure.enabled': False})


def check_target(sectors, bearing: float, rng_m: float) -> None:
    """The brightest cell of every sector within one beam and one bin of the target; the FLS front
    end's brightest region within one resolution cell of it."""
    for a, g, _ in sectors:
        i, j = np.unravel_index(np.argmax(a), a.shape)
        assert abs(g.bearings()[j] - bearing) <= g.angle_increment, (math.degrees(g.bearings()[j]),
                                                                     math.degrees(bearing))
        assert abs(g.ranges()[i] - rng_m) <= g.range_resolution
    proc = FlsProcessor(fls_config())
    frames = []
    for a, g, stamp in sectors:
        frames += proc.add_sector(a, g, (0.0, 0.0, 0.0), stamp / 1e9)
    last = proc.flush()
    regions = np.concatenate([f.regions for f in frames + ([last] if last is not None else [])])
    best = regions[np.argmax(regions['f03'])]
    g = sectors[0][1]
    res = proc.config.image.resolution
    cell = math.hypot(max(g.range_resolution, res), max(rng_m * g.angle_increment, res))
    assert math.hypot(best['x'] - rng_m * math.cos(bearing), best['y'] - rng_m * math.sin(bearing)) <= cell


def didson_table(n: int = 96) -> np.ndarray:
    """Beam bearings [deg], column 0 to starboard: spacing 0.23 deg at the centre to 0.37 deg at the edges."""
    k = np.arange(n - 1)
    spacing = 0.23 + 0.14 * np.abs(k - (n - 2) / 2) / ((n - 2) / 2)
    a = np.concatenate([[0.0], np.cumsum(spacing)])
    return a - a[-1] / 2


def test_readme_steps_on_polar_frames_with_an_angle_table(tmp_path, monkeypatch, capsys):
    meta = readme_yaml('polar')
    folder = tmp_path / 'didson_export'
    folder.mkdir()
    table = didson_table()
    # The column where spreading the first and last angle evenly misplaces a beam the most.
    naive = np.linspace(table[0], table[-1], len(table))
    j = int(np.argmax(np.abs(naive - table)))
    assert abs(naive[j] - table[j]) > 2.5 * np.mean(np.diff(table))   # the error the table avoids: 0.84 deg
    (folder / meta['beam_angles_deg']).write_text('beam,angle_deg\n' + ''.join(f'{i},{a:.4f}\n'
                                                                               for i, a in enumerate(table)))
    n_bins = 501
    ranges = np.linspace(meta['range_min'], meta['range_max'], n_bins)
    i = int(np.argmin(np.abs(ranges - TARGET_RANGE)))
    rng = np.random.default_rng(61)
    import cv2
    for k in range(N_FRAMES):
        v = rng.integers(30, 60, (n_bins, len(table))).astype(np.uint8)
        v[i - 4:i + 5, j - 1:j + 2] = 200          # a fish 18 cm long, 3 beams wide
        v[i, j] = 240
        stamp = f'20240506_101512.{100 * k:03d}'     # T0 + 0.1 k, as a UTC date-time
        cv2.imwrite(str(folder / f'{stamp}.png'), v[::-1] if meta['rows'] == 'far_first' else v)
    (folder / 'sonar.yaml').write_text(yaml.safe_dump(meta))
    inspected, imported = run_readme_steps(folder, tmp_path, monkeypatch, capsys)
    assert 'angle table of 96 beams' in inspected and 'resampled onto an even grid' in inspected
    assert 'stamps from the file names' in inspected
    sectors = read_sectors(tmp_path / 'rec_sectors')
    assert [s for *_, s in sectors] == [int(round((T0 + 0.1 * k) * 1e9)) for k in range(N_FRAMES)]
    g = sectors[0][1]
    assert g.n_beams == 96 and math.isclose(g.angle_min, math.radians(table[0]), abs_tol=1e-6)
    check_target(sectors, math.radians(table[j]), ranges[i])


def fan_picture(meta: dict, rng: np.random.Generator, target: tuple[float, float]) -> np.ndarray:
    """A Cartesian fan picture as exported: speckle inside the fan, 0 outside, forward up, port left,
    and a fish at the target (range, bearing): 240 at its centre, 4 pixels standard deviation."""
    u0, v0 = meta['apex_px']
    s = meta['metres_per_pixel']
    h, w = v0 + 20, 2 * u0 + 1
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
    x, y = (v0 - vv) * s, (u0 - uu) * s
    r, b = np.hypot(x, y), np.degrees(np.arctan2(y, x))
    inside = (r >= meta['range_min']) & (r <= meta['range_max']) & (np.abs(b) <= meta['fov_deg'] / 2)
    img = np.where(inside, rng.integers(30, 60, (h, w)), 0).astype(np.uint8)
    tr, tb = target
    d2 = ((x - tr * math.cos(tb)) ** 2 + (y - tr * math.sin(tb)) ** 2) / s**2
    spot = np.rint(240 * np.exp(-d2 / (2 * 4.0**2)))
    return np.where(inside, np.maximum(img, spot), 0).astype(np.uint8)


def test_readme_steps_on_cartesian_fan_images(tmp_path, monkeypatch, capsys):
    import cv2
    meta = readme_yaml('fan')
    folder = tmp_path / 'aris_export'
    folder.mkdir()
    rng = np.random.default_rng(62)
    target = (4.5, math.radians(9.0))                  # to port
    rows = ['file,time']
    for k in range(N_FRAMES):
        name = f'frame_{k:04d}.png'
        cv2.imwrite(str(folder / name), fan_picture(meta, rng, target))
        rows.append(f'{name},2024-05-06T10:15:{12 + k}.250+00:00')
    (folder / meta['stamps']).write_text('\n'.join(rows) + '\n')
    (folder / 'sonar.yaml').write_text(yaml.safe_dump(meta))
    inspected, _ = run_readme_steps(folder, tmp_path, monkeypatch, capsys)
    assert 'Cartesian fan images' in inspected and f'stamps from {meta["stamps"]}' in inspected
    sectors = read_sectors(tmp_path / 'rec_sectors')
    assert [s for *_, s in sectors] == [int(round((T0 + k + 0.25) * 1e9)) for k in range(N_FRAMES)]
    a, g, _ = sectors[0]
    s = meta['metres_per_pixel']
    assert math.isclose(g.range_resolution, s, rel_tol=1e-6)                       # a bin per pixel
    assert math.isclose(g.angle_increment, s / meta['range_max'], rel_tol=0.01)     # a pixel at far range
    # The cells fill the fan: centres half a cell inside its edges.
    assert math.isclose(g.range_min, meta['range_min'] + s / 2, rel_tol=1e-6)
    assert math.isclose(g.angle_min, -math.radians(meta['fov_deg']) / 2 + g.angle_increment / 2, rel_tol=1e-6)
    assert a.dtype == np.uint8 and a.min() >= 30    # every cell is the fan's speckle: nothing of the 0s outside
    check_target(sectors, target[1], target[0])


def test_a_fan_partly_outside_the_picture_has_no_data_there(tmp_path, capsys):
    """Cells of the fan beyond the picture's edge are 0 (no measurement), the rest is the picture."""
    import cv2
    meta = {k: v for k, v in readme_yaml('fan').items() if k != 'stamps'}
    folder = tmp_path / 'cropped'
    folder.mkdir()
    img = fan_picture(meta, np.random.default_rng(63), (3.0, 0.0))
    cv2.imwrite(str(folder / 'f0.png'), img[:, 380:])         # the port half cut off
    meta['apex_px'] = [meta['apex_px'][0] - 380, meta['apex_px'][1]]
    (folder / 'sonar.yaml').write_text(yaml.safe_dump(meta))
    assert sonar_import([str(folder), '-o', str(tmp_path / 'out')]) == 0, capsys.readouterr().err
    (a, g, _), = read_sectors(tmp_path / 'out')
    port = g.bearings() > math.radians(2.0)    # more than 20 px left of the apex at 6 m
    assert np.all(a[:, port][-10:] == 0) and np.all(a[:, ~port] > 0)


@pytest.mark.parametrize('name,stamp', [
    ('20240506_101512.250.png', T0 + 0.25),
    ('sonar_2024-05-06T10-15-12_0001.png', T0),
    ('frame_1714990512.25.npy', T0 + 0.25),
    ('1714990512250.png', T0 + 0.25),
    ('f0001.png', None),
])
def test_stamps_from_file_names(name, stamp):
    from sonar_tracking.io.importers.frame_folder import stamp_from_name
    got = stamp_from_name(name)
    assert got == stamp if stamp is None else math.isclose(got, stamp, abs_tol=1e-6)


@pytest.mark.parametrize('forward', ['right', 'down', 'left', 'mirrored'])
def test_fan_pictures_turned_or_mirrored(tmp_path, capsys, forward):
    """The same fan drawn with forward right, down or left, or mirrored (port on the right, read with
    head_clockwise): the target comes out at the same range and bearing, to port."""
    import cv2
    meta = {k: v for k, v in readme_yaml('fan').items() if k != 'stamps'}
    target = (4.5, math.radians(9.0))
    img = fan_picture(meta, np.random.default_rng(64), target)
    (h, w), (u0, v0) = img.shape, meta['apex_px']
    if forward == 'right':
        img, apex = cv2.rotate(img, cv2.ROTATE_90_CLOCKWISE), [h - 1 - v0, u0]
    elif forward == 'down':
        img, apex = cv2.rotate(img, cv2.ROTATE_180), [w - 1 - u0, h - 1 - v0]
    elif forward == 'left':
        img, apex = cv2.rotate(img, cv2.ROTATE_90_COUNTERCLOCKWISE), [v0, w - 1 - u0]
    else:
        img, apex = img[:, ::-1], [w - 1 - u0, v0]
        meta['head_clockwise'] = True
    meta.update(apex_px=apex, forward='up' if forward == 'mirrored' else forward, start_time=T0)
    folder = tmp_path / 'fan'
    folder.mkdir()
    cv2.imwrite(str(folder / 'f0.png'), np.ascontiguousarray(img))
    (folder / 'sonar.yaml').write_text(yaml.safe_dump(meta))
    assert sonar_import([str(folder), '-o', str(tmp_path / 'out')]) == 0, capsys.readouterr().err
    (a, g, _), = read_sectors(tmp_path / 'out')
    i, j = np.unravel_index(np.argmax(a), a.shape)
    assert abs(g.bearings()[j] - target[1]) <= g.angle_increment
    assert abs(g.ranges()[i] - target[0]) <= g.range_resolution
