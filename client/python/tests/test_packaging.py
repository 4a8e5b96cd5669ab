"""The package as installed from its wheel: imported from the virtual environment (not the
source tree), its generated stubs from the system protoc, and its pinned dependency ranges
against what is installed (Debian's grpcio, protobuf and numpy)."""
import importlib.metadata
import os
import re
import sys
from pathlib import Path

import google.protobuf
from packaging.requirements import Requirement
from packaging.version import Version

import skinserve
import skinserve.v1
from skinserve.v1 import skinning_pb2


def requirements():
    return {r.name: r for r in map(Requirement, importlib.metadata.requires("skinserve"))}


def test_imported_from_the_virtual_environment_not_the_source_tree():
    package = Path(skinserve.__file__).resolve()
    assert sys.prefix != sys.base_prefix, "not running in a virtual environment"
    assert package.is_relative_to(Path(sys.prefix).resolve()), package
    source = os.environ.get("SKINSERVE_SOURCE_DIR")
    assert source, "set SKINSERVE_SOURCE_DIR to the repository"
    assert not package.is_relative_to(Path(source, "client", "python").resolve()), package


def test_typed_package_with_stubs_from_the_system_protoc():
    package = Path(skinserve.__file__).parent
    assert (package / "py.typed").is_file()
    assert (package / "v1" / "skinning_pb2.pyi").is_file()
    # protoc >= 3.20's gencode builds messages with the runtime's builder; 3.5.1's (Debian's
    # grpc_tools) made descriptors directly, which protobuf >= 4.21 refuses to import.
    assert "_builder.BuildTopDescriptorsAndMessages" in \
        Path(skinning_pb2.__file__).read_text()
    assert re.fullmatch(r"3\.21\.\d+", skinserve.v1.PROTOC_VERSION)


def test_pinned_protobuf_range_accepts_the_installed_one_and_matches_protoc():
    protobuf = requirements()["protobuf"]
    installed = importlib.metadata.version("protobuf")
    assert installed == google.protobuf.__version__
    assert protobuf.specifier.contains(installed), (str(protobuf), installed)
    # The lower bound is the gencode's own version: protoc 3.<m> is the Python runtime 4.<m>
    # (protobuf's versioning since 21), the oldest runtime that gencode is guaranteed on.
    minor = int(skinserve.v1.PROTOC_VERSION.split(".")[1])
    lower = [Version(s.version) for s in protobuf.specifier if s.operator == ">="]
    assert lower == [Version(f"4.{minor}")], str(protobuf)
    # The runtime of grpc_tools' old gencode (3.5) and the next major (5) are outside.
    assert not protobuf.specifier.contains("3.5.1")
    assert not protobuf.specifier.contains("5.26.0")


def test_pinned_grpcio_and_numpy_ranges_accept_the_installed_ones():
    for name in ("grpcio", "numpy"):
        requirement, installed = requirements()[name], importlib.metadata.version(name)
        assert requirement.specifier.contains(installed), (str(requirement), installed)


def test_public_names():
    assert set(skinserve.__all__) == {"AsyncClient", "AsyncFrameSocket", "Character",
                                      "CharacterResult", "ClipTrack",
                                      "Client", "FrameSocket", "FrameWeights", "MorphTarget",
                                      "Pose",
                                      "PoseLayer", "SkinserveError", "SharedMemoryRegion",
                                      "Weights", "decode_values"}
