"""ament_python package flex_model; also pip-installable (pip install [-e] src/flex_model)."""
import os
from glob import glob

from setuptools import find_packages, setup

package_name = 'flex_model'
# setuptools wants data_files paths relative to this directory (colcon and pip both run here).
os.chdir(os.path.dirname(os.path.abspath(__file__)))
presets = sorted(glob(os.path.join(package_name, 'presets', '*.yaml')))
scenarios = sorted(glob(os.path.join(package_name, 'presets', 'scenarios', '*.yaml')))
spatial = sorted(glob(os.path.join(package_name, 'presets', 'spatial', '*.yaml'))
                 + glob(os.path.join(package_name, 'presets', 'spatial', '*.urdf')))

data_files = [
    ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
    ('share/' + package_name, ['package.xml']),
]
if presets:
    # also under share/ so that get_package_share_directory('flex_model') finds them in a
    # colcon install; the copy inside the Python package (package_data) is the primary one.
    data_files.append(('share/' + package_name + '/presets', presets))
if scenarios:
    data_files.append(('share/' + package_name + '/presets/scenarios', scenarios))
if spatial:
    data_files.append(('share/' + package_name + '/presets/spatial', spatial))

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['presets/*.yaml', 'presets/scenarios/*.yaml',
                                 'presets/spatial/*.yaml', 'presets/spatial/*.urdf']},
    data_files=data_files,
    install_requires=['numpy', 'scipy', 'numba', 'pyyaml', 'matplotlib'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='flex-twin maintainers',
    maintainer_email='flex-twin@example.com',
    description='flex-twin: flexible-link robot arm models, simulation core and model node',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'flex-model-node = flex_model.ros.model_node:main',
            'model_node = flex_model.ros.model_node:main',
            'flex-spatial-model-node = flex_model.ros.model_node:spatial_main',
            'spatial_model_node = flex_model.ros.model_node:spatial_main',
        ],
    },
)
