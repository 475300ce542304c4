"""ament_python build script for ifc_spg (Jazzy template)."""

from glob import glob
import hashlib
import os
import sys
import tarfile
import tempfile
import urllib.request

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
                      depends=['ifc_spg/kernels/collision_core.h'],
                      include_dirs=[numpy.get_include()], extra_compile_args=['-O2'],
                      optional=True),
            # the Popov-Vereshchagin sweeps (numpy fallback: ifc_spg/dynamics/native.py)
            Extension('ifc_spg.dynamics._native_dynamics',
                      ['ifc_spg/dynamics/_native_dynamics.c'],
                      include_dirs=[numpy.get_include()], extra_compile_args=['-O2'],
                      optional=True),
            *coal_extension(numpy.get_include()), *daqp_extension()]


#: DAQP's sdist on PyPI, the version requirements.lock pins (daqp==...): the headers of
#: its C sources (csrc/include, MIT) declare the C API that ifc_spg.cascade._daqp_native
#: calls in the daqp module's binary. (URL, sha256.)
DAQP_VERSION = '0.11.0'
DAQP_SDIST = ('https://files.pythonhosted.org/packages/c2/5d/'
              '6ae925a74c02e68a1356a49261dc42af98fa1cda75c16428e49cb7b1f0f9/daqp-0.11.0.tar.gz',
              '2f27baf18d2acca14186498e651b34e0bed455627e777d3fd8ba655e7e40f920')


def _sha256(path):
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for chunk in iter(lambda: f.read(1 << 16), b''):
            digest.update(chunk)
    return digest.hexdigest()


def daqp_headers():
    """DAQP's C headers from the pinned sdist, fetched once; their directory, or None.

    The sdist is taken from $IFC_SPG_DAQP_SDIST (a local copy) or ~/.cache/ifc_spg/
    (downloaded there from PyPI if absent), its sha256 checked, and its csrc/include and
    LICENSE unpacked into build/ (not in git). None, with a note, where it cannot be had
    (offline) or IFC_SPG_DAQP_SDIST=0: the cascade then calls DAQP through its Python module.
    """
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.join(here, 'build', f'daqp-{DAQP_VERSION}')
    include = os.path.join(root, 'csrc', 'include')
    if os.path.isfile(os.path.join(include, 'api.h')):
        return include
    url, sha = DAQP_SDIST
    sdist = os.environ.get('IFC_SPG_DAQP_SDIST', '')
    if sdist == '0':
        return None
    if not sdist:
        cache = os.path.join(os.environ.get('XDG_CACHE_HOME') or
                             os.path.join(os.path.expanduser('~'), '.cache'), 'ifc_spg')
        sdist = os.path.join(cache, os.path.basename(url))
        if not os.path.isfile(sdist) or _sha256(sdist) != sha:
            try:
                os.makedirs(cache, exist_ok=True)
                with urllib.request.urlopen(url, timeout=60) as r, \
                        tempfile.NamedTemporaryFile(dir=cache, delete=False) as f:
                    f.write(r.read())
                os.replace(f.name, sdist)
            except OSError as e:
                print(f'ifc_spg: DAQP sources not fetched ({e}); the cascade will call DAQP '
                      'through its Python module', file=sys.stderr)
                return None
    if not os.path.isfile(sdist) or _sha256(sdist) != sha:
        print(f'ifc_spg: {sdist} is not the DAQP {DAQP_VERSION} sdist (sha256 differs); the '
              'cascade will call DAQP through its Python module', file=sys.stderr)
        return None
    prefix = f'daqp-{DAQP_VERSION}/'
    with tarfile.open(sdist, 'r:gz') as tar:
        members = [m for m in tar.getmembers() if m.isfile() and '..' not in m.name and
                   (m.name.startswith(prefix + 'csrc/include/') or
                    m.name == prefix + 'LICENSE')]
        for m in members:
            m.name = m.name[len(prefix):]
        tar.extractall(root, members)
    return include


def daqp_extension():
    """ifc_spg.cascade._daqp_native: the cascade's DAQP solves from C (optional).

    It calls DAQP's C functions in the installed daqp module's binary (the same machine
    code as the Python path, see _daqp_native.c), declared by the headers of the same
    version's sdist.
    """
    include = daqp_headers()
    if include is None:
        return []
    rel = os.path.relpath(include, os.path.dirname(os.path.abspath(__file__)))
    return [Extension('ifc_spg.cascade._daqp_native', ['ifc_spg/cascade/_daqp_native.c'],
                      include_dirs=[rel], libraries=['dl'],
                      define_macros=[('IFC_SPG_DAQP_VERSION', f'"{DAQP_VERSION}"')],
                      extra_compile_args=['-O2'], optional=True)]


def coal_extension(numpy_include):
    """The collision narrowphase in C++ on coal (ifc_spg/kernels/_coal_native.cpp).

    Optional, like the C kernels: it needs the headers and libraries of the cmeel wheels that
    pin brings (coal, pinocchio, boost.python) and Eigen's headers from the ``cmeel-eigen``
    wheel (requirements.lock), all in the installed ``cmeel.prefix``; without them (or a C++
    compiler) the collision level uses pinocchio's Python bindings, see
    ifc_spg/kernels/__init__.py. ``EIGEN3_INCLUDE_DIR`` names another Eigen 3.4 (development).
    """
    import importlib.util
    import sysconfig

    spec = importlib.util.find_spec('coal')  # .../cmeel.prefix/lib/pythonX.Y/site-packages/coal
    if spec is None or spec.origin is None:
        return []
    prefix = os.path.abspath(os.path.join(os.path.dirname(spec.origin), *[os.pardir] * 4))
    include, lib = os.path.join(prefix, 'include'), os.path.join(prefix, 'lib')
    eigen = os.environ.get('EIGEN3_INCLUDE_DIR') or os.path.join(include, 'eigen3')
    python = 'boost_python' + sysconfig.get_config_var('py_version_nodot')
    needed = [os.path.join(include, 'coal', 'distance.h'),
              os.path.join(include, 'pinocchio', 'spatial.hpp'),
              os.path.join(eigen, 'Eigen', 'Core'), os.path.join(lib, 'libcoal.so'),
              os.path.join(lib, f'lib{python}.so')]
    missing = [p for p in needed if not os.path.exists(p)]
    if missing:
        print(f"ifc_spg: not building ifc_spg.kernels._coal_native (missing {', '.join(missing)})")
        return []
    return [Extension('ifc_spg.kernels._coal_native', ['ifc_spg/kernels/_coal_native.cpp'],
                      depends=['ifc_spg/kernels/collision_core.h'],
                      language='c++', include_dirs=[numpy_include, include, eigen],
                      library_dirs=[lib], libraries=['coal', python], runtime_library_dirs=[lib],
                      # the defines of coal.pc; no -march: Eigen's alignment must be coal's
                      define_macros=[('COAL_HAS_OCTOMAP', None), ('COAL_HAVE_OCTOMAP', None),
                                     ('OCTOMAP_MAJOR_VERSION', '1'),
                                     ('OCTOMAP_MINOR_VERSION', '10'),
                                     ('OCTOMAP_PATCH_VERSION', '0')],
                      extra_compile_args=['-O2', '-std=c++17', '-Wno-deprecated-declarations'],
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
