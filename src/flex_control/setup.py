"""ament_python package flex_control; also pip-installable (pip install [-e] src/flex_control)."""
import os

from setuptools import find_packages, setup

package_name = 'flex_control'
# setuptools wants data_files paths relative to this directory (colcon and pip both run here).
os.chdir(os.path.dirname(os.path.abspath(__file__)))

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    # flex_model is a ROS exec_depend (package.xml); it is not listed here so that pip never
    # tries to fetch it from an index: scripts/bootstrap.sh installs it from src/ first.
    install_requires=['numpy', 'scipy', 'pyyaml'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='flex-twin maintainers',
    maintainer_email='flex-twin@example.com',
    description='flex-twin: controllers for flexible-link robot arms and controller node',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'flex-controller-node = flex_control.controller_node:main',
            'controller_node = flex_control.controller_node:main',
        ],
        # in-loop controllers for the model node (flex_model.controller_interface)
        'flex_twin.controllers': [
            'eq95 = flex_control.in_loop:eq95',
            'eq45 = flex_control.in_loop:eq45',
            'state_feedback = flex_control.in_loop:state_feedback',
        ],
    },
)
