from setuptools import find_packages, setup

package_name = 'itasc_drivers'

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
    description=('Drivers and Sensors of iTaSC-ROS2: simulated robot, adapters to existing ROS 2 drivers '
                 '(ros2_control, JointTrajectory), pose sensors.'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'simulated_robot = itasc_drivers.simulated_robot:main',
            'fake_ros2_control = itasc_drivers.fake_ros2_control:main',
        ],
        'itasc.drivers': [
            'ros2_control = itasc_drivers.drivers.ros2_control:Ros2Control',
            'simulated = itasc_drivers.drivers.simulated:Simulated',
        ],
    },
)
