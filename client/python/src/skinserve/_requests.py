"""The requests both clients send: a mesh's upload messages and a frame's SkinRequest,
built from checked arrays."""
from typing import Any, Iterable, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

from . import _arrays, _morph, _shared_memory
from ._morph import FrameWeights, MorphTarget
from ._shared_memory import SharedMemoryRegion
from .v1 import skinning_pb2 as pb

CHUNK_BYTES = 1 << 20
ENCODINGS = {"float32": pb.ENCODING_FLOAT32, "float16": pb.ENCODING_FLOAT16,
             "snorm16": pb.ENCODING_SNORM16}


REST_ENCODINGS = {"float32": pb.REST_ENCODING_FLOAT32,
                  "quantized16": pb.REST_ENCODING_QUANTIZED16,
                  "quantized8-weights": pb.REST_ENCODING_QUANTIZED8_WEIGHTS}


def upload_requests(positions: npt.NDArray[np.float32], joints: npt.NDArray[np.uint16],
                    weights: npt.NDArray[np.float32],
                    normals: Optional[npt.NDArray[np.float32]], normalize_weights: bool,
                    joint_count: Optional[int],
                    morph_targets: Optional[Sequence[MorphTarget]] = None,
                    tangents: Optional[npt.NDArray[np.float32]] = None,
                    rest_encoding: str = "float32"
                    ) -> List[pb.UploadMeshRequest]:
    """The header, then each array in chunks of at most 1 MiB."""
    if rest_encoding not in REST_ENCODINGS:
        raise ValueError(f"rest_encoding: {rest_encoding!r}, expected one of "
                         f"{', '.join(REST_ENCODINGS)}")
    _arrays.check_mesh(positions, joints, weights, normals)
    if tangents is not None:
        _arrays.check_tangents(tangents, positions.shape[0], normals is not None)
    targets = list(morph_targets or [])
    sizes, morph_normals, morph_tangents = _morph.check_targets(
        targets, positions.shape[0], normals is not None, tangents is not None)
    used = int(joints.max()) + 1
    if joint_count is None:
        joint_count = used
    elif not isinstance(joint_count, int) or joint_count < used:
        raise ValueError(f"joint_count: {joint_count!r}, expected an int >= {used} "
                         f"(joints refers to joint {used - 1})")
    header = pb.MeshHeader(
        vertex_count=positions.shape[0], influences=joints.shape[1],
        joint_count=joint_count, has_normals=normals is not None,
        weight_policy=(pb.WEIGHT_POLICY_NORMALIZE if normalize_weights
                       else pb.WEIGHT_POLICY_REJECT),
        morph_target_sizes=sizes, morph_normals=morph_normals,
        has_tangents=tangents is not None, morph_tangents=morph_tangents,
        rest_encoding=REST_ENCODINGS[rest_encoding])
    requests = [pb.UploadMeshRequest(header=header)]
    arrays: List[Tuple[pb.MeshArray, Optional[npt.NDArray[Any]], str]] = [
        (pb.MESH_ARRAY_POSITIONS, positions, "f4"),
        (pb.MESH_ARRAY_NORMALS, normals, "f4"),
        (pb.MESH_ARRAY_JOINTS, joints, "u2"),
        (pb.MESH_ARRAY_WEIGHTS, weights, "f4"),
        (pb.MESH_ARRAY_TANGENTS, tangents, "f4")]
    arrays += _morph.target_arrays(targets)
    for kind, array, dtype in arrays:
        if array is None:
            continue
        data = _arrays.little_endian_bytes(array, dtype)
        itemsize = np.dtype(dtype).itemsize
        for offset in range(0, len(data), CHUNK_BYTES):
            requests.append(pb.UploadMeshRequest(chunk=pb.MeshChunk(
                array=kind, offset=offset // itemsize, data=data[offset:offset + CHUNK_BYTES])))
    return requests


def check_encoding(encoding: str) -> None:
    if encoding not in ENCODINGS:
        raise ValueError(f"encoding: '{encoding}', expected one of {sorted(ENCODINGS)}")


def skin_request(mesh_id: str, palette: Optional[npt.NDArray[np.float32]],
                 crowd: Optional[int], frame: int, backend: Optional[str], want_normals: bool,
                 encoding: str, region: Optional[SharedMemoryRegion] = None, offset: int = 0,
                 morph_weights: Optional[FrameWeights] = None,
                 want_tangents: bool = False) -> pb.SkinRequest:
    """A frame's request; palette None: no palette (the caller sets a pose, _pose.set_pose)."""
    check_encoding(encoding)
    palette_bytes = b"" if palette is None else _arrays.little_endian_bytes(palette, "f4")
    request = pb.SkinRequest(mesh_id=mesh_id, backend=backend or "", frame=frame,
                             palette=palette_bytes,
                             want_normals=want_normals, want_tangents=want_tangents,
                             encoding=ENCODINGS[encoding],
                             instances=crowd or 0, pack_instances=True)
    _morph.set_weights(request, morph_weights, crowd)
    if region is not None:
        if region.name is None:
            raise ValueError("region: not registered (Client.register_region)")
        request.output.region = region.name
        request.output.offset = offset
    return request


def stream_weights(morph_weights: Optional[Iterable[Optional[FrameWeights]]],
                   frames: int) -> List[Optional[FrameWeights]]:
    """A stream's weights, one entry (or None) per palette; None: no frame has any."""
    if morph_weights is None:
        return [None] * frames
    weights = list(morph_weights)
    if len(weights) != frames:
        raise ValueError(f"morph_weights: {len(weights)} entries, expected one per palette "
                         f"({frames})")
    return weights


def check_window(window: int) -> None:
    if window < 1:
        raise ValueError(f"window: {window}, expected >= 1")


def region_stride(vertices: int, crowds: List[Optional[int]], want_normals: bool,
                  encoding: str, window: int, region: SharedMemoryRegion,
                  want_tangents: bool = False) -> int:
    """Bytes between a stream's frames in `region`: the largest frame, rounded up; the
    region must hold `window` of them."""
    check_encoding(encoding)
    size = 4 if encoding == "float32" else 2
    stride = max((_shared_memory.frame_bytes(vertices, k or 1, size, want_normals,
                                             want_tangents)
                  for k in set(crowds)), default=0)
    if window * stride > region.byte_size:
        raise ValueError(f"region: {region.byte_size} bytes, fewer than {window} frames "
                         f"in flight of {stride} bytes")
    return stride
