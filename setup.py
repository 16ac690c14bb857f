"""ament_python build of sonar_tracking (also installable with plain pip)."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'sonar_tracking'

# Every executable is a console script installed into lib/sonar_tracking (see setup.cfg),
# which is where `ros2 run sonar_tracking NAME` looks.
CONSOLE_SCRIPTS = [
    'seaking_sim = sonar_tracking.nodes.seaking_sim:main',
    'active_detector = sonar_tracking.nodes.active_detector:main',
    'imm_ipda_tracker = sonar_tracking.nodes.imm_ipda_tracker:main',
    'fls_features = sonar_tracking.nodes.fls_features:main',
    'gpf_tracker = sonar_tracking.nodes.gpf_tracker:main',
    'projected_sonar_adapter = sonar_tracking.nodes.projected_sonar_adapter:main',
    'sonar_eval = sonar_tracking.cli.sonar_eval:main',
    'sonar_stack = sonar_tracking.cli.sonar_stack:main',
    'sonar_echo = sonar_tracking.cli.sonar_echo:main',
    'bag_record = sonar_tracking.cli.bag_record:main',
    'bag_replay = sonar_tracking.cli.bag_replay:main',
    'sonar_import = sonar_tracking.cli.sonar_import:main',
    'sonar_view = sonar_tracking.cli.sonar_view:main',
]

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(include=[PACKAGE, PACKAGE + '.*']),
    package_data={PACKAGE: ['data/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', sorted(glob('config/*.yaml'))),
        ('share/' + PACKAGE + '/config/sensors', sorted(glob('config/sensors/*.yaml'))),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='sonar_tracking developers',
    maintainer_email='sonar-tracking@example.org',
    description='Sonar tracking stack for AUVs: ESC thresholding, IMM-IPDA, FLS features, GPF.',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={'console_scripts': CONSOLE_SCRIPTS},
)
