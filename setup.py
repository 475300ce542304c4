"""ament_python build script for ifc_spg (Jazzy template)."""

from glob import glob
import os

from setuptools import Extension, find_packages, setup

package_name = 'ifc_spg'


def tree(src, dst):
    """Return data_files entries that install every file below ``src`` into ``dst``."""
    entries = {}
    for path in glob(os.path.join(src, '**', '*'), recursive=True):
        if os.path.isfile(path):
            rel = os.path.relpath(os.path.dirname(path), src)
            entries.setdefault(os.path.normpath(os.path.join(dst, rel)), []).append(path)
    return sorted(entries.items())


def native_extensions():
    """The C kernels of the 2 ms path.

    Optional: without a compiler or numpy the package falls back to its numpy code, see
    ifc_spg/kernels/__init__.py.
    """
    try:
        import numpy
    except ImportError:
        return []
    return [Extension('ifc_spg.kernels._native', ['ifc_spg/kernels/_native.c'],
                      include_dirs=[numpy.get_include()], extra_compile_args=['-O2'],
                      optional=True),
            # the Popov-Vereshchagin sweeps (numpy fallback: ifc_spg/dynamics/native.py)
            Extension('ifc_spg.dynamics._native_dynamics',
                      ['ifc_spg/dynamics/_native_dynamics.c'],
                      include_dirs=[numpy.get_include()], extra_compile_args=['-O2'],
                      optional=True)]


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'experiments', 'experiments.*',
                                    'benchmarks', 'benchmarks.*']),
    package_data={'ifc_spg': ['py.typed', 'model/data/*', 'schema/*.json']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/schema', ['ifc_spg/schema/task_stack.schema.json']),
        *tree('config', os.path.join('share', package_name, 'config')),
    ],
    ext_modules=native_extensions(),
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='ifc_spg developers',
    maintainer_email='ifc-spg@users.noreply.github.com',
    description='Set-point generation and task specification for indirect force controlled robots',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'spg_node = ifc_spg.entry:spg_node',
            'sim_bridge = ifc_spg.entry:sim_bridge',
            'task_publisher = ifc_spg.entry:task_publisher',
            'ifc-spg = ifc_spg.entry:ifc_spg',
        ],
    },
)
