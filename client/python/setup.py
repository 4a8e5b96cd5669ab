"""Generates the gRPC stubs from the repository's .proto while the package is built.

The .proto is looked up at ../../proto (this folder inside the repository) or at
$SKINSERVE_PROTO_DIR. The stubs land in the built package as skinserve/v1/, so the
generated imports (`from skinserve.v1 import skinning_pb2`) resolve inside it.
"""
import os
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
PROTO = "skinserve/v1/skinning.proto"


def proto_dir():
    candidates = [os.environ.get("SKINSERVE_PROTO_DIR"), HERE.parent.parent / "proto"]
    for c in candidates:
        if c and (Path(c) / PROTO).is_file():
            return Path(c)
    raise RuntimeError(f"{PROTO} not found in {candidates}: build from the repository "
                       "checkout or set SKINSERVE_PROTO_DIR")


class BuildWithStubs(build_py):
    def run(self):
        super().run()
        from grpc_tools import protoc  # build-time only (Debian: python3-grpc-tools)

        out = Path(self.build_lib)
        (out / "skinserve" / "v1").mkdir(parents=True, exist_ok=True)
        source = proto_dir()
        code = protoc.main(["grpc_tools.protoc", f"-I{source}", f"--python_out={out}",
                            f"--grpc_python_out={out}", str(source / PROTO)])
        if code != 0:
            raise RuntimeError(f"grpc_tools.protoc failed on {source / PROTO}")
        (out / "skinserve" / "v1" / "__init__.py").write_text(
            '"""Generated from skinserve/v1/skinning.proto at build time."""\n')


setup(cmdclass={"build_py": BuildWithStubs})
