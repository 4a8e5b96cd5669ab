"""Generates the protobuf messages from the repository's .proto while the package is built.

The system protoc (`protoc` on PATH, or $PROTOC; Debian 12: protobuf-compiler 3.21.12)
writes skinning_pb2.py (--python_out) and its type stubs skinning_pb2.pyi (--pyi_out)
into the built package as skinserve/v1/, so the imports `from .v1 import skinning_pb2`
resolve inside it. The gRPC method table is skinserve/_service.py (why: see there).
pyproject.toml's protobuf range follows this protoc: protoc 3.21 is protobuf 21, whose
Python runtime is 4.21; gencode runs on a runtime of its version or newer within that
major (protobuf's cross-version guarantee), hence protobuf >= 4.21, < 5. The version is
recorded in skinserve/v1/__init__.py (PROTOC_VERSION) and the tests compare both.

The .proto is looked up at ../../proto (this folder inside the repository) or at
$SKINSERVE_PROTO_DIR.
"""
import os
import re
import shutil
import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
PROTO = "skinserve/v1/skinning.proto"


def proto_dir() -> Path:
    candidates = [os.environ.get("SKINSERVE_PROTO_DIR"), HERE.parent.parent / "proto"]
    for c in candidates:
        if c and (Path(c) / PROTO).is_file():
            return Path(c)
    raise RuntimeError(f"{PROTO} not found in {candidates}: build from the repository "
                       "checkout or set SKINSERVE_PROTO_DIR")


def protoc() -> str:
    path = os.environ.get("PROTOC") or shutil.which("protoc")
    if not path:
        raise RuntimeError("protoc not found on PATH (Debian: protobuf-compiler) and "
                           "$PROTOC not set")
    return path


class BuildWithStubs(build_py):
    def run(self) -> None:
        super().run()
        out = Path(self.build_lib)
        (out / "skinserve" / "v1").mkdir(parents=True, exist_ok=True)
        source, compiler = proto_dir(), protoc()
        version = subprocess.run([compiler, "--version"], check=True, capture_output=True,
                                 text=True).stdout.strip()
        match = re.fullmatch(r"libprotoc (3\.21\.\d+)", version)
        if not match:
            raise RuntimeError(f"{compiler} is '{version}', expected libprotoc 3.21.x: "
                               "pyproject.toml's protobuf range is for its gencode")
        subprocess.run([compiler, f"-I{source}", f"--python_out={out}", f"--pyi_out={out}",
                        str(source / PROTO)], check=True)
        (out / "skinserve" / "v1" / "__init__.py").write_text(
            '"""Generated from skinserve/v1/skinning.proto at build time."""\n'
            f'PROTOC_VERSION = "{match.group(1)}"\n')


setup(cmdclass={"build_py": BuildWithStubs})
