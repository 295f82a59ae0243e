"""setuptools glue for pyproject.toml: build `_schnee_native` with the project's CMake build.

Everything declarative lives in pyproject.toml; this file only adds the CMake-driven extension
(setuptools cannot describe a CMake target) and the stable-ABI wheel tag.
"""
import os
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext
from wheel.bdist_wheel import bdist_wheel

ROOT = os.path.dirname(os.path.abspath(__file__))


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[], py_limited_api=True)


class CMakeBuild(build_ext):
    """Configure a private CMake tree (no engine, no tests needed) and build one target into the
    package folder of the wheel being assembled."""

    def build_extension(self, ext):
        out_dir = os.path.dirname(os.path.abspath(self.get_ext_fullpath(ext.name)))
        tree = os.path.join(os.path.abspath(self.build_temp), "cmake")
        subprocess.run(["cmake", "-S", ROOT, "-B", tree, "-DCMAKE_BUILD_TYPE=Release",
                        "-DSCHNEE_BUILD_ENGINE=OFF", f"-DSCHNEE_PYTHON_MODULE_DIR={out_dir}"],
                       check=True)
        subprocess.run(["cmake", "--build", tree, "--target", "_schnee_native", "-j",
                        str(os.cpu_count() or 1)], check=True)

    def get_ext_filename(self, ext_name):
        # CMake names the module _schnee_native.abi3.so (PEP 384 stable ABI).
        return os.path.join(*ext_name.split(".")[:-1], ext_name.split(".")[-1] + ".abi3.so")


class AbiWheel(bdist_wheel):
    def get_tag(self):
        python, abi, plat = super().get_tag()
        return "cp311", "abi3", plat


# Keep setuptools' own trees out of build/ (the CMake tree of scripts/build.sh) and out of addon/.
os.makedirs(os.path.join(ROOT, "build-wheel"), exist_ok=True)
setup(ext_modules=[CMakeExtension("schnee_probes._schnee_native")],
      cmdclass={"build_ext": CMakeBuild, "bdist_wheel": AbiWheel},
      options={"build": {"build_base": "build-wheel"}, "egg_info": {"egg_base": "build-wheel"},
               "bdist_wheel": {"bdist_dir": "build-wheel/bdist"}})
