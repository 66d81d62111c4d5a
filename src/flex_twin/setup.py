"""ament_python package flex_twin; also pip-installable (pip install [-e] src/flex_twin)."""
import os

from setuptools import find_packages, setup

package_name = 'flex_twin'
os.chdir(os.path.dirname(os.path.abspath(__file__)))

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        # ros2 launch flex_twin suite.launch.py (ros2_ws/launch and ros2_ws/params link here)
        ('share/' + package_name + '/launch', ['launch/suite.launch.py']),
        ('share/' + package_name + '/params', ['params/suite.yaml']),
    ],
    install_requires=['flex_model', 'flex_control', 'flex_planner', 'numpy', 'scipy',
                      'pyyaml', 'matplotlib', 'mcap', 'mcap-ros2-support', 'rosbags',
                      'distributed'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='flex-twin maintainers',
    maintainer_email='flex-twin@example.com',
    description='flex-twin: the flex-twin command, bags, suite launcher, demos, diagnosis, '
                'real arms and comparisons on top of flex_model, flex_control, flex_planner',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'flex-twin = flex_twin.cli:main',
        ],
    },
)
