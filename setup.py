"""Build the compiled kernels: every ``.pyx`` under ``lcpcli/`` becomes an extension module.

    python setup.py build_ext --inplace -j 2     # in a checkout (tests run from the tree)
    pip install -e ".[test]"                     # editable install, builds the same in place
    pip install .                                # a normal install (wheel built locally)

Compiler flags: ``-O3 -g0``.  OpenMP (``-fopenmp``) only for the modules listed in
:data:`OPENMP_MODULES`, and only when the compiler accepts it (else they build serial:
Cython's ``prange`` then runs as a plain loop).  See docs/kernels.md.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent
#: Modules that use ``prange`` (OpenMP); the others are built without it.
OPENMP_MODULES = {"lcpcli.analysis._enum", "lcpcli.contact._blocks",
                  "lcpcli.solvers.kernels.batch", "lcpcli.solvers.kernels.stack_c"}
#: Set ``LCPCLI_NO_OPENMP=1`` to build every module serial.
NO_OPENMP = os.environ.get("LCPCLI_NO_OPENMP", "") not in ("", "0")


def pyx_modules() -> list[tuple[str, str]]:
    """(module name, path) of every ``.pyx`` under ``lcpcli/`` (sorted)."""
    out = []
    for path in sorted((ROOT / "lcpcli").rglob("*.pyx")):
        rel = path.relative_to(ROOT)
        out.append((".".join(rel.with_suffix("").parts), rel.as_posix()))
    return out


def openmp_flags() -> list[str]:
    """``["-fopenmp"]`` when the C compiler builds and links an OpenMP program, else []."""
    if NO_OPENMP or sys.platform == "win32":
        return []  # MSVC's /openmp is 2.0 only; Windows wheels are serial
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    cc = new_compiler()
    customize_compiler(cc)
    tmp = tempfile.mkdtemp()
    try:
        src = os.path.join(tmp, "omp.c")
        with open(src, "w") as f:
            f.write("#include <omp.h>\nint main(void){return omp_get_max_threads() < 1;}\n")
        try:
            objs = cc.compile([src], output_dir=tmp, extra_postargs=["-fopenmp"])
            cc.link_executable(objs, os.path.join(tmp, "omp"), extra_postargs=["-fopenmp"])
        except Exception:  # noqa: BLE001 - any failure means: no OpenMP
            print("setup.py: the C compiler has no OpenMP; building serial kernels",
                  file=sys.stderr)
            return []
        return ["-fopenmp"]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def extensions() -> list[Extension]:
    """One Extension per ``.pyx`` (sources still ``.pyx``: :class:`BuildExt` cythonizes)."""
    headers = [str(p.relative_to(ROOT)) for p in sorted((ROOT / "lcpcli").rglob("*.h"))]
    return [Extension(name, [path], depends=headers) for name, path in pyx_modules()]


class BuildExt(build_ext):
    """Cythonize and compile only when extensions are built (not when pip asks for metadata),
    with OpenMP where used and available, and in parallel by default (``pip install`` passes
    no ``-j``: one job per CPU)."""

    def finalize_options(self) -> None:
        super().finalize_options()
        if not self.parallel:
            self.parallel = os.cpu_count() or 1

    def run(self) -> None:
        import numpy
        from Cython.Build import cythonize

        omp = openmp_flags()
        # -g0: no debug information (Python's own CFLAGS add -g: a quarter of the build time)
        base = ["-O3", "-g0"] if sys.platform != "win32" else ["/O2"]
        for ext in self.extensions:
            ext.include_dirs.append(numpy.get_include())
            ext.extra_compile_args = base + (omp if ext.name in OPENMP_MODULES else [])
            ext.extra_link_args = omp if ext.name in OPENMP_MODULES else []
            ext.define_macros.append(("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION"))
        done = cythonize(
            self.extensions,
            compiler_directives={"language_level": "3", "boundscheck": False,
                                 "wraparound": False, "cdivision": True,
                                 "initializedcheck": False},
            nthreads=int(os.environ.get("LCPCLI_CYTHON_JOBS", "0")) or os.cpu_count() or 1,
            quiet=True)
        sources = {e.name: e.sources for e in done}  # the .c files, on setuptools' extensions
        for ext in self.extensions:
            ext.sources = sources[ext.name]
        super().run()
        if self.inplace:  # editable install / checkout: write the bytecode now, so that the
            import compileall  # first run after installing is not slower than the second

            compileall.compile_dir(str(ROOT / "lcpcli"), quiet=1)


setup(ext_modules=extensions(), cmdclass={"build_ext": BuildExt})
