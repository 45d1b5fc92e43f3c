"""Build step for slamkit's C kernels (everything else is in pyproject.toml).

The kernels are ordinary CPython extension modules compiled when the package is installed
(``pip install .`` or ``pip install -e .``), never at run time. Each is optional: without a C
compiler the install still succeeds and slamkit runs its pure-Python/numpy fallbacks, which the
test suite checks agree with the kernels (``SLAMKIT_NO_NATIVE=1`` forces them).
"""

from setuptools import Extension, setup

KERNELS = {
    "slamkit.data.formats._textscan": "slamkit/data/formats/_textscan.c",
    "slamkit.maps._raycast": "slamkit/maps/_raycast.c",
    "slamkit.planning._gridsearch": "slamkit/planning/_gridsearch.c",
    "slamkit.estimation._pfkernel": "slamkit/estimation/_pfkernel.c",
    "slamkit.estimation._eskfkernel": "slamkit/estimation/_eskfkernel.c",
    "slamkit.frontend._bnbkernel": "slamkit/frontend/_bnbkernel.c",
    "slamkit.frontend._icpkernel": "slamkit/frontend/_icpkernel.c",
}

setup(ext_modules=[Extension(name, [source], extra_compile_args=["-O3"], libraries=["m"], optional=True)
                   for name, source in KERNELS.items()])
