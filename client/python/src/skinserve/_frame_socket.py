"""FrameSocket: frames over the server's frame socket (skinserve --frame-socket PATH,
docs/serving/frame-socket.md), for a client on the server's host: the same requests and
answers as Client.skin, without gRPC. The protocol (skinserve/wire/frame_socket_protocol.h):
the 8 bytes b"SKFRAME1", then each message a 4-byte little-endian length and a serialized
SkinRequest (ours) or SkinResponse part (the server's); the server's last message has the
length's top bit set and its `error` says why the connection ends."""
import socket
import struct
from typing import Any, Optional, Tuple

import grpc
import numpy as np
import numpy.typing as npt

from ._client import Client
from ._errors import SkinserveError, status_code
from ._frame import Answer, Frame
from ._morph import FrameWeights
from ._shared_memory import SharedMemoryRegion
from .v1 import skinning_pb2 as pb

HELLO = b"SKFRAME1"
END_BIT = 0x80000000


class FrameSocket:
    """A connection to the frame socket at `path`. `client` builds the requests (its
    default backend, re-uploads are not done here: a lost mesh is SkinserveError
    NOT_FOUND) and registers the regions frames name: the same process owns them on both
    doors. One frame at a time; use one FrameSocket per thread."""

    def __init__(self, path: str, client: Client) -> None:
        self._client = client
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self._sock.connect(path)
        except OSError as e:
            self._sock.close()
            raise SkinserveError(grpc.StatusCode.UNAVAILABLE,
                                 f"cannot connect to the frame socket {path}: {e}") from e
        try:
            self._sock.sendall(HELLO)
        except OSError:
            pass  # refused and closed already: the first read gives the server's reason
        self._end: Optional[Tuple[Any, str]] = None

    def close(self) -> None:
        self._sock.close()

    def __enter__(self) -> "FrameSocket":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
             backend: Optional[str] = None, want_normals: bool = False,
             encoding: str = "float32", frame: int = 0,
             region: Optional[SharedMemoryRegion] = None, offset: int = 0,
             morph_weights: Optional[FrameWeights] = None,
             want_tangents: bool = False) -> Answer:
        """As Client.skin; a frame's own error (bad input, a region not this process's) is
        SkinserveError and the connection goes on; the connection's end (refused, quiet
        too long, the server draining) is SkinserveError with the server's reason."""
        crowd, request = self._client._skin_request(  # pylint: disable=protected-access
            mesh_id, palette, backend, want_normals, encoding, frame, region, offset,
            morph_weights, want_tangents)
        self._send(request)
        result = Frame(crowd)
        while True:
            part = self._read()
            result.add_part(part, want_normals, region)
            if part.last:
                break
        if result.error is not None:
            raise SkinserveError(result.error[0], result.error[1], request.frame)
        return result.result(want_normals, want_tangents)

    def _send(self, request: pb.SkinRequest) -> None:
        body = request.SerializeToString()
        try:
            self._sock.sendall(struct.pack("<I", len(body)) + body)
        except OSError:
            self._read()  # the server ended the connection: its reason, if it gave one
            raise

    def _read_exactly(self, size: int) -> bytes:
        chunks, left = [], size
        while left:
            chunk = self._sock.recv(left)
            if not chunk:
                raise SkinserveError(grpc.StatusCode.UNAVAILABLE,
                                     "the frame socket closed without saying why")
            chunks.append(chunk)
            left -= len(chunk)
        return b"".join(chunks)

    def _read(self) -> pb.SkinResponse:
        if self._end is not None:
            raise SkinserveError(*self._end)
        (header,) = struct.unpack("<I", self._read_exactly(4))
        part = pb.SkinResponse()
        part.ParseFromString(self._read_exactly(header & 0x7FFFFFFF))
        if header & END_BIT:
            self._end = (status_code(part.error.code), part.error.message)
            raise SkinserveError(*self._end)
        return part
