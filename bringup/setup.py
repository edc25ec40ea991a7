import os

from setuptools import find_packages, setup

package_name = 'itasc_bringup'


def config_data_files():
    """The repo's top-level config/ tree (application models, robot descriptions, named
    configurations), recursively, symlinks followed, into share/itasc_bringup/config."""
    # Sources must be relative (colcon asserts it) to this package's real directory:
    # colcon runs this file through a symlink in build/itasc_bringup, hence realpath.
    here = os.path.dirname(os.path.realpath(__file__))
    config_dir = os.path.join(os.path.dirname(here), 'config')
    entries = {os.path.join('share', package_name, 'config'): []}
    for dirpath, dirnames, filenames in os.walk(config_dir, followlinks=True):
        dirnames[:] = sorted(d for d in dirnames if d != '__pycache__' and not d.startswith('.'))
        rel = os.path.relpath(dirpath, config_dir)
        dest = os.path.normpath(os.path.join('share', package_name, 'config', rel))
        files = [os.path.relpath(os.path.join(dirpath, f), here)
                 for f in sorted(filenames) if not f.startswith('.')]
        if files:
            entries.setdefault(dest, []).extend(files)
    return sorted(entries.items())


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ] + config_data_files(),
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='iTaSC-ROS2 maintainers',
    maintainer_email='itasc-ros2@example.com',
    description=('Bootstrap (root Composer) of iTaSC-ROS2 applications, the application models under config/, and the '
                 'plot and graph tools.'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'bootstrap = itasc_bringup.bootstrap:main',
            'itasc-plot = itasc_bringup.plot:main',
            'itasc-foxglove = itasc_bringup.visualization.layout:main',
            'itasc-graph = itasc_bringup.graph:main',
            'itasc-replay = itasc_bringup.replay:main',
            'itasc-recover = itasc_bringup.recording.recover:main',
            'itasc-model = itasc_bringup.model.cli:main',
            'host_agent = itasc_core.composition.host_agent:main',
        ],
    },
)
