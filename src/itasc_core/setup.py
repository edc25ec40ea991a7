from setuptools import find_packages, setup

package_name = 'itasc_core'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['communication/fastdds.xml', 'communication/fastdds_localhost.xml',
                                'communication/fastdds_peers.xml.in']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='iTaSC-ROS2 maintainers',
    maintainer_email='itasc-ros2@example.com',
    description=('Composition Pattern runtime of iTaSC-ROS2 (entities, events, life-cycle FSM, composer, configurator,'
                 ' scheduler, monitors, ports) and the constraint-based program entities (Robot, Object, Scene, '
                 'Solver).'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [],
        'itasc.conditions': [
            'above = itasc_core.computation.conditions.builtin:Above',
            'below = itasc_core.computation.conditions.builtin:Below',
            'outside = itasc_core.computation.conditions.builtin:Outside',
            'stale = itasc_core.computation.conditions.builtin:Stale',
            'nonfinite = itasc_core.computation.conditions.builtin:NonFinite',
            'inside = itasc_core.computation.conditions.inside:Inside',
        ],
        'itasc.solvers': [
            'qp = itasc_core.itasc.solver.qp:QpSolver',
            'wdls = itasc_core.itasc.solver.wdls:WdlsSolver',
        ],
    },
)
