from setuptools import find_packages, setup

package_name = 'itasc_tasks'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='iTaSC-ROS2 maintainers',
    maintainer_email='itasc-ros2@example.com',
    description=('Task composites of iTaSC-ROS2: virtual kinematic chains, constraint outputs, constraint controllers,'
                 ' setpoint generators.'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [],
        'itasc.task_types': [
            'cartesian = itasc_tasks.task_types.cartesian:Cartesian',
            'distance = itasc_tasks.task_types.distance:Distance',
            'joint = itasc_tasks.task_types.joint:Joint',
            'point_plane = itasc_tasks.task_types.point_plane:PointPlane',
        ],
        'itasc.controllers': [
            'p = itasc_tasks.controllers.p:PController',
            'pid = itasc_tasks.controllers.pid:PIDController',
        ],
        'itasc.setpoint_generators': [
            'fixed = itasc_tasks.setpoints.fixed:Fixed',
            'hold = itasc_tasks.setpoints.hold:Hold',
            'minimum_jerk = itasc_tasks.setpoints.minimum_jerk:MinimumJerk',
            'periodic = itasc_tasks.setpoints.periodic:Periodic',
            'topic = itasc_tasks.setpoints.topic:Topic',
            'trapezoidal = itasc_tasks.setpoints.trapezoidal:Trapezoidal',
        ],
    },
)
