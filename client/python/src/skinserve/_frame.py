"""Frame: one frame's response parts assembled into float32 arrays, for both clients."""
from typing import Any, NoReturn, Optional, Tuple, Union

import grpc
import numpy as np
import numpy.typing as npt

from . import _encoding
from ._errors import SkinserveError, status_code
from ._shared_memory import SharedMemoryRegion
from .v1 import skinning_pb2 as pb

FloatArray = npt.NDArray[np.float32]
# A frame's answer: positions, or (positions, normals) with want_normals, or (positions,
# normals, tangents) with want_tangents too.
Answer = Union[FloatArray, Tuple[FloatArray, FloatArray],
               Tuple[FloatArray, FloatArray, FloatArray]]


def _bounds(b: pb.Bounds) -> Tuple[float, float, float, float, float, float]:
    return (b.min_x, b.min_y, b.min_z, b.max_x, b.max_y, b.max_z)


class Frame:
    """One frame's parts, assembled into float32 arrays: (V, 3) for a single palette, or
    (K, V, 3) for a crowd of K instances (`crowd` = K). Parts come instance by instance,
    each in vertex order, or several whole instances in one part (packed:
    SkinResponse.instance_count); one that does not fit the frame fails it (INTERNAL)."""

    def __init__(self, crowd: Optional[int] = None) -> None:
        self.crowd = crowd
        self.positions: Optional[FloatArray] = None
        self.normals: Optional[FloatArray] = None
        self.tangents: Optional[FloatArray] = None  # (K, V, 4) x y z w, when the parts carry them
        self.error: Optional[Tuple[Any, str]] = None  # (grpc.StatusCode, message)
        self._next = (0, 0)  # the (instance, first vertex) the next part must start at

    def _fail(self, part: pb.SkinResponse, what: str) -> NoReturn:
        raise SkinserveError(grpc.StatusCode.INTERNAL, f"malformed answer: {what}", part.frame)

    def add_part(self, part: pb.SkinResponse, want_normals: bool,
                 region: Optional[SharedMemoryRegion]) -> None:
        if part.HasField("region_write"):
            self._add_region(part, want_normals, region)
        else:
            self._add(part, want_normals)

    def _add(self, part: pb.SkinResponse, want_normals: bool) -> None:
        if part.HasField("error"):
            self.error = (status_code(part.error.code), part.error.message)
            return
        instances = max(part.instances, 1)  # a server without crowds leaves it 0
        if instances != (self.crowd or 1):
            self._fail(part, f"{instances} instances, {self.crowd or 1} asked for")
        if self.positions is None:
            shape = (instances, part.total_vertices, 3)
            self.positions = np.empty(shape, dtype=np.float32)
            if want_normals:
                self.normals = np.empty(shape, dtype=np.float32)
            if part.tangents:
                self.tangents = np.empty((instances, part.total_vertices, 4), dtype=np.float32)
        total = self.positions.shape[1]
        packed = max(part.instance_count, 1)  # whole instances in this part
        end = part.first_vertex + part.vertex_count
        if (part.instance, part.first_vertex) != self._next or part.total_vertices != total \
                or end > total or part.instance + packed > instances \
                or (packed > 1 and (part.first_vertex != 0 or end != total)):
            self._fail(part, f"part of instance {part.instance} ({packed} packed), vertices "
                       f"[{part.first_vertex}, {end}) of {part.total_vertices}, expected "
                       f"instance {self._next[0]} from vertex {self._next[1]} of {total}")
        if packed > 1 and part.encoding == _encoding.SNORM16 \
                and len(part.instance_bounds) != packed:
            self._fail(part, f"{packed} instances in the part but "
                       f"{len(part.instance_bounds)} instance_bounds")
        self._next = (part.instance + packed, 0) if end == total else (part.instance, end)
        if part.last and self._next != (instances, 0):
            self._fail(part, f"the frame ended at instance {self._next[0]}, vertex "
                       f"{self._next[1]}")
        positions, normals = memoryview(part.positions), memoryview(part.normals)
        if len(positions) % packed or len(normals) % packed:
            self._fail(part, f"{len(positions)} and {len(normals)} bytes of positions and "
                       f"normals for {packed} instances")
        tangents = memoryview(part.tangents)
        if (self.tangents is not None) != bool(len(tangents)) or len(tangents) % packed:
            self._fail(part, f"{len(tangents)} bytes of tangents for {packed} instances")
        rows = slice(part.first_vertex, end)
        p_size, n_size = len(positions) // packed, len(normals) // packed
        t_size = len(tangents) // packed
        for j in range(packed):
            k = part.instance + j
            b = part.instance_bounds[j] if packed > 1 and part.encoding == _encoding.SNORM16 \
                else part.bounds
            self.positions[k, rows] = _encoding.decode_values(
                positions[j * p_size:(j + 1) * p_size], part.encoding, part.vertex_count,
                _bounds(b))
            if self.normals is not None:
                self.normals[k, rows] = _encoding.decode_values(
                    normals[j * n_size:(j + 1) * n_size], part.encoding, part.vertex_count,
                    normals=True)
            if self.tangents is not None:
                self.tangents[k, rows] = _encoding.decode_values(
                    tangents[j * t_size:(j + 1) * t_size], part.encoding, part.vertex_count,
                    normals=True, width=4)

    def _add_region(self, part: pb.SkinResponse, want_normals: bool,
                    region: Optional[SharedMemoryRegion]) -> None:
        """The frame's one part when it went into `region`: arrays that view the region
        (float32 and float16: no copy; snorm16 is decoded into new arrays)."""
        write = part.region_write
        if region is None or region.buffer is None or write.region != region.name:
            self._fail(part, f"answered in region '{write.region}', which the frame did not name")
        buffer = region.buffer
        instances, vertices = max(part.instances, 1), part.total_vertices
        if instances != (self.crowd or 1) or not part.last:
            self._fail(part, f"{instances} instances in region '{write.region}'")
        dtype = {_encoding.FLOAT32: "<f4", _encoding.FLOAT16: "<f2",
                 _encoding.SNORM16: "<i2"}[part.encoding]
        count = instances * vertices * 3
        size = count * np.dtype(dtype).itemsize
        if write.instance_bytes * instances != size or write.end_offset > region.byte_size \
                or write.positions_offset + size > region.byte_size:
            self._fail(part, f"ranges of region '{write.region}' do not fit the frame")

        def view(offset: int, normals: bool, width: int = 3) -> Any:
            values = np.frombuffer(buffer, dtype=dtype, count=count // 3 * width, offset=offset)
            values = values.reshape(instances, vertices, width)
            if part.encoding != _encoding.SNORM16:
                return values  # float32, or float16 as the region holds it
            out = np.empty(values.shape, dtype=np.float32)
            for k in range(instances):
                out[k] = _encoding.decode_values(
                    values[k].tobytes(), part.encoding, vertices,
                    _bounds(part.instance_bounds[k]), normals=normals, width=width)
            return out

        self.positions = view(write.positions_offset, False)
        if want_normals:
            self.normals = view(write.normals_offset, True)
        if write.tangent_instance_bytes:  # x y z w, 4 values a vertex
            tangent_size = size // 3 * 4
            if write.tangent_instance_bytes * instances != tangent_size \
                    or write.tangents_offset + tangent_size > region.byte_size:
                self._fail(part, f"tangents of region '{write.region}' do not fit the frame")
            self.tangents = view(write.tangents_offset, True, 4)

    def result(self, want_normals: bool, want_tangents: bool = False) -> Answer:
        if self.positions is None:
            raise SkinserveError(grpc.StatusCode.INTERNAL, "malformed answer: no parts")
        single = self.crowd is None  # (V, 3) arrays, not (1, V, 3)
        positions: FloatArray = self.positions[0] if single else self.positions
        normals: Optional[FloatArray] = None
        if not want_normals:
            return positions
        if self.normals is None:
            raise SkinserveError(grpc.StatusCode.INTERNAL, "malformed answer: no normals")
        normals = self.normals[0] if single else self.normals
        if not want_tangents:
            return positions, normals
        if self.tangents is None:
            raise SkinserveError(grpc.StatusCode.INTERNAL, "malformed answer: no tangents")
        tangents: FloatArray = self.tangents[0] if single else self.tangents
        return positions, normals, tangents
