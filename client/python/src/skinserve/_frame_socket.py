"""FrameSocket and AsyncFrameSocket: frames and ticks over the server's frame socket
(skinserve --frame-socket PATH, docs/serving/frame-socket.md), for a client on the server's
host: the same requests and answers as Client.skin and Client.tick, without gRPC. The
protocol (skinserve/wire/frame_socket_protocol.h): the 8 bytes b"SKFRAME1", then each
message a 4-byte little-endian length and a serialized SkinRequest (ours) or SkinResponse
part (the server's); the server's last message has the length's top bit set and its `error`
says why the connection ends. The two classes share everything but their reads and writes
(_Decoder); neither uploads a lost mesh again (a frame raises, a tick's character fails
NOT_FOUND): uploads belong to the gRPC client."""
import asyncio
import socket
import struct
from typing import Any, Callable, List, Optional, Sequence, Tuple, Union

import grpc
import numpy as np
import numpy.typing as npt

from . import _tick
from ._aio_client import AsyncClient
from ._client import Client
from ._errors import SkinserveError, status_code
from ._frame import Answer, Frame
from ._morph import FrameWeights
from ._shared_memory import SharedMemoryRegion
from ._tick import Character, CharacterResult, TickAnswer
from .v1 import skinning_pb2 as pb

HELLO = b"SKFRAME1"
END_BIT = 0x80000000
_CLOSED = "the frame socket closed without saying why"


def _message(request: pb.SkinRequest) -> bytes:
    body: bytes = request.SerializeToString()
    return struct.pack("<I", len(body)) + body


class _Decoder:
    """The server's messages, as both classes read them: a header's size and end bit, a part,
    and the connection's end once its last message said why (every later read raises it)."""

    def __init__(self) -> None:
        self.end: Optional[Tuple[Any, str]] = None

    def header(self, data: bytes) -> Tuple[int, bool]:
        """A message's size and whether it is the server's last."""
        if self.end is not None:
            raise SkinserveError(*self.end)
        (header,) = struct.unpack("<I", data)
        return header & 0x7FFFFFFF, bool(header & END_BIT)

    def part(self, body: bytes, last: bool) -> pb.SkinResponse:
        part = pb.SkinResponse()
        part.ParseFromString(body)
        if last:
            self.end = (status_code(part.error.code), part.error.message)
            raise SkinserveError(*self.end)
        return part


def _frame_request(client: Union[Client, AsyncClient], mesh_id: str, palette: Any,
                   options: Tuple[Any, ...]) -> Tuple[Optional[int], pb.SkinRequest]:
    return client._skin_request(mesh_id, palette, *options)  # pylint: disable=protected-access


def _tick_request(client: Union[Client, AsyncClient], characters: Sequence[Character],
                  frame: int) -> Tuple[TickAnswer, pb.SkinRequest]:
    characters = list(characters)
    crowds = _tick.check_characters(characters,
                                    client._joint_count)  # pylint: disable=protected-access
    return TickAnswer(characters, crowds, frame), _tick.tick_request(characters, crowds, frame)


def _frame_result(result: Frame, request: pb.SkinRequest, want_normals: bool,
                  want_tangents: bool) -> Answer:
    if result.error is not None:
        raise SkinserveError(result.error[0], result.error[1], request.frame)
    return result.result(want_normals, want_tangents)


class FrameSocket:
    """A connection to the frame socket at `path`. `client` builds the requests (its
    default backend; the joint counts of the meshes it uploaded) and registers the regions
    frames name: the same process owns them on both doors. One request at a time; use one
    FrameSocket per thread."""

    def __init__(self, path: str, client: Client) -> None:
        self._client = client
        self._decoder = _Decoder()
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
        crowd, request = _frame_request(self._client, mesh_id, palette,
                                        (backend, want_normals, encoding, frame, region, offset,
                                         morph_weights, want_tangents))
        result = Frame(crowd)
        self._send(request)
        self._read_answer(lambda part: result.add_part(part, want_normals, region))
        return _frame_result(result, request, want_normals, want_tangents)

    def tick(self, characters: Sequence[Character], frame: int = 0) -> List[CharacterResult]:
        """As Client.tick: one CharacterResult per character in order, a bad character
        failing alone (its result's error names it); a tick refused whole raises
        SkinserveError. A character whose mesh the server lost fails NOT_FOUND."""
        answer, request = _tick_request(self._client, characters, frame)
        self._send(request)
        self._read_answer(answer.add_part)
        return answer.answered()

    def _read_answer(self, add: Callable[[pb.SkinResponse], None]) -> None:
        while True:
            part = self._read()
            add(part)
            if part.last:
                return

    def _send(self, request: pb.SkinRequest) -> None:
        try:
            self._sock.sendall(_message(request))
        except OSError:
            self._read()  # the server ended the connection: its reason, if it gave one
            raise

    def _read_exactly(self, size: int) -> bytes:
        chunks, left = [], size
        while left:
            chunk = self._sock.recv(left)
            if not chunk:
                raise SkinserveError(grpc.StatusCode.UNAVAILABLE, _CLOSED)
            chunks.append(chunk)
            left -= len(chunk)
        return b"".join(chunks)

    def _read(self) -> pb.SkinResponse:
        size, last = self._decoder.header(self._read_exactly(4))
        return self._decoder.part(self._read_exactly(size), last)


class AsyncFrameSocket:
    """FrameSocket for asyncio, beside an AsyncClient:

        async with skinserve.AsyncFrameSocket(path, client) as frames:
            vertices = await frames.skin(mesh_id, palette)
            results = await frames.tick(characters)

    One request at a time (a lock keeps concurrent callers' requests and answers in order);
    open one per task that needs its own pace. It reads and writes the socket through the
    event loop's socket calls rather than asyncio streams: a stream drops the bytes it holds
    when a write fails, and with them the server's reason for ending the connection."""

    def __init__(self, path: str, client: AsyncClient) -> None:
        self._path, self._client = path, client
        self._decoder = _Decoder()
        self._sock: Optional[socket.socket] = None
        self._lock = asyncio.Lock()

    async def connect(self) -> "AsyncFrameSocket":
        loop = asyncio.get_running_loop()
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.setblocking(False)
        try:
            await loop.sock_connect(sock, self._path)
        except OSError as e:
            sock.close()
            raise SkinserveError(grpc.StatusCode.UNAVAILABLE,
                                 f"cannot connect to the frame socket {self._path}: {e}") from e
        self._sock = sock
        try:
            await loop.sock_sendall(sock, HELLO)
        except OSError:
            pass  # refused and closed already: the first read gives the server's reason
        return self

    async def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    async def __aenter__(self) -> "AsyncFrameSocket":
        return await self.connect()

    async def __aexit__(self, *exc: Any) -> None:
        await self.close()

    async def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
                   backend: Optional[str] = None, want_normals: bool = False,
                   encoding: str = "float32", frame: int = 0,
                   region: Optional[SharedMemoryRegion] = None, offset: int = 0,
                   morph_weights: Optional[FrameWeights] = None,
                   want_tangents: bool = False) -> Answer:
        """FrameSocket.skin."""
        crowd, request = _frame_request(self._client, mesh_id, palette,
                                        (backend, want_normals, encoding, frame, region, offset,
                                         morph_weights, want_tangents))
        result = Frame(crowd)
        await self._exchange_one(request,
                                 lambda part: result.add_part(part, want_normals, region))
        return _frame_result(result, request, want_normals, want_tangents)

    async def tick(self, characters: Sequence[Character],
                   frame: int = 0) -> List[CharacterResult]:
        """FrameSocket.tick."""
        answer, request = _tick_request(self._client, characters, frame)
        await self._exchange_one(request, answer.add_part)
        return answer.answered()

    async def _exchange_one(self, request: pb.SkinRequest,
                            add: Callable[[pb.SkinResponse], None]) -> None:
        async with self._lock:
            if self._sock is None:
                raise SkinserveError(grpc.StatusCode.FAILED_PRECONDITION,
                                     "AsyncFrameSocket: not connected (async with, or connect())")
            try:
                await asyncio.get_running_loop().sock_sendall(self._sock, _message(request))
            except OSError:
                await self._read()  # the server ended the connection: its reason, if it gave one
                raise
            while True:
                part = await self._read()
                add(part)
                if part.last:
                    return

    async def _read_exactly(self, size: int) -> bytes:
        assert self._sock is not None
        loop = asyncio.get_running_loop()
        chunks, left = [], size
        while left:
            chunk = await loop.sock_recv(self._sock, left)
            if not chunk:
                raise SkinserveError(grpc.StatusCode.UNAVAILABLE, _CLOSED)
            chunks.append(chunk)
            left -= len(chunk)
        return b"".join(chunks)

    async def _read(self) -> pb.SkinResponse:
        size, last = self._decoder.header(await self._read_exactly(4))
        return self._decoder.part(await self._read_exactly(size), last)
