"""Builds the native BVH (``raytracer/_native/bvh.cc``), POV-Ray's anti-aliasing rule
(``antialias.cc``), stream compaction (``compact.cc``) and the compiled programs' run-time warnings
(``notice.cc``), called from JAX through XLA's FFI, at install.

Everything else about the package is in ``pyproject.toml``. The extension is optional: without a
C++ compiler the package still installs and renders with the pure-JAX path (``raytracer info``
says which one a render uses). The XLA FFI headers come from the ``jaxlib`` wheel (a build
requirement), so nothing but a C++17 compiler is needed.
"""

from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class BuildWithXlaHeaders(build_ext):
    def build_extensions(self):
        import jaxlib

        include = Path(jaxlib.__file__).parent / "include"
        for ext in self.extensions:
            ext.include_dirs.append(str(include))
        super().build_extensions()


setup(
    ext_modules=[
        Extension(
            "raytracer._native._bvh",
            ["raytracer/_native/bvh.cc", "raytracer/_native/antialias.cc", "raytracer/_native/compact.cc",
             "raytracer/_native/notice.cc"],
            depends=["raytracer/_native/kinds.h"],
            language="c++",
            extra_compile_args=["-std=c++17", "-O3", "-fno-math-errno"],
            optional=True,
        )
    ],
    cmdclass={"build_ext": BuildWithXlaHeaders},
)
