"""Client: the Skinning service as NumPy arrays in, NumPy arrays out (blocking calls)."""
import contextlib
import queue
import threading
import time
from typing import (Any, Callable, Dict, Generator, Iterable, Iterator, List, Literal,
                    Optional, Sequence, Tuple, Union, overload)

import grpc
import numpy as np
import numpy.typing as npt

from . import _answers, _arrays, _channel, _requests, _tick
from ._errors import SkinserveError, rpc_error
from ._frame import Answer, FloatArray, Frame
from ._morph import FrameWeights, MorphTarget
from ._shared_memory import SharedMemoryRegion
from ._tick import Character, CharacterResult
from ._service import SkinningStub
from .v1 import skinning_pb2 as pb


class _IdleWatchdog:
    """Cancels `call` when no answer came for `limit` seconds while one was awaited (see the
    C++ library's IdleWatchdog): a stream has no deadline, but must not wait for ever on a
    server that stopped answering."""

    def __init__(self, call: Any, limit: Optional[float]) -> None:
        self._call, self._limit = call, limit
        self._last, self._awaiting = time.monotonic(), False
        self._done = threading.Event()
        self.fired = False
        if limit:
            self._thread = threading.Thread(target=self._watch, args=(limit,), daemon=True)
            self._thread.start()

    def answered(self) -> None:
        self._last = time.monotonic()

    def awaiting(self, value: bool) -> None:
        if value and not self._awaiting:
            self._last = time.monotonic()
        self._awaiting = value

    def _watch(self, limit: float) -> None:
        while not self._done.is_set():
            idle = time.monotonic() - self._last
            if self._awaiting and idle >= limit:
                self.fired = True
                self._call.cancel()
                return
            self._done.wait(limit - idle if self._awaiting else limit)

    def stop(self) -> None:
        self._done.set()


class Client:
    """A connection to skinserve at `target` ("host:port", or any gRPC target such as
    "dns:///skinserve.default.svc:50051", balanced with round_robin).

    TLS: `tls_ca` (the PEM file of the CA that signed the server's certificate) turns it on;
    `tls_cert` and `tls_key` present this client's certificate (mutual TLS);
    `tls_server_name` is the name the server's certificate must carry when the target's
    host is not it (an IP address). unix: targets are plaintext on the server's side.

    Every call has a deadline: `timeout` seconds (uploads: `upload_timeout`); a stream whose
    frames wait `stream_idle_timeout` seconds without an answer ends (DEADLINE_EXCEEDED) and
    resumes on a new stream like one ended UNAVAILABLE. With calls open the channel pings the
    server every `keepalive` seconds and gives up on one that does not answer within
    `keepalive_timeout` (UNAVAILABLE). None: no limit.

    Meshes uploaded through this client are remembered: a frame answered NOT_FOUND (the
    replica evicted the mesh, or the call landed on another replica) uploads the mesh
    again and resends the frame, as the C++ client library does.

    skinserve.AsyncClient has the same methods for asyncio.
    """

    def __init__(self, target: str, max_reuploads: int = 8, max_reconnects: int = 3,
                 tls_ca: Optional[str] = None, tls_cert: Optional[str] = None,
                 tls_key: Optional[str] = None, tls_server_name: Optional[str] = None,
                 timeout: Optional[float] = 30.0, upload_timeout: Optional[float] = 300.0,
                 stream_idle_timeout: Optional[float] = 30.0,
                 keepalive: Optional[float] = 10.0, keepalive_timeout: float = 5.0) -> None:
        self.target = target
        self.max_reuploads, self.max_reconnects = max_reuploads, max_reconnects
        self.timeout, self.upload_timeout = timeout, upload_timeout
        self.stream_idle_timeout = stream_idle_timeout
        credentials = _channel.credentials(tls_ca, tls_cert, tls_key, tls_server_name)
        options = _channel.options(keepalive, keepalive_timeout, tls_server_name)
        if credentials is None:
            self._channel = grpc.insecure_channel(target, options=options)
        else:
            self._channel = grpc.secure_channel(target, credentials, options=options)
        self._stub = SkinningStub(self._channel)
        # mesh id -> (requests to upload it again, joint count, vertex count)
        self._meshes: Dict[str, Tuple[List[pb.UploadMeshRequest], int, int]] = {}

    def close(self) -> None:
        self._channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ---- meshes -----------------------------------------------------------------------
    def upload(self, positions: npt.NDArray[np.float32], joints: npt.NDArray[np.uint16],
               weights: npt.NDArray[np.float32],
               normals: Optional[npt.NDArray[np.float32]] = None,
               normalize_weights: bool = False, joint_count: Optional[int] = None,
               morph_targets: Optional[Sequence[MorphTarget]] = None,
               tangents: Optional[npt.NDArray[np.float32]] = None,
               rest_encoding: str = "float32") -> str:
        """Stores a mesh and returns its id (the SHA-256 of its content).

        positions, normals: float32 (V, 3); joints: uint16 (V, B); weights: float32 (V, B),
        1 <= B <= 8. Weights must sum to 1 per vertex unless normalize_weights is set.
        joint_count: the palettes' length (default: the largest joint id + 1).
        morph_targets: skinserve.MorphTarget(indices, positions, normals=None,
        tangents=None) each, sparse: the vertices a target moves (uint32, ascending) and
        their deltas (float32 (D, 3); tangent deltas move xyz and need `tangents`); frames
        then name their active targets' weights (skin's morph_weights).
        tangents: float32 (V, 4), glTF TANGENT (xyz unit, w +1 or -1); needs normals.
        rest_encoding: how the server stores the mesh: "float32", or "quantized16" /
        "quantized8-weights" (16-bit positions, normals and weights, or 8-bit weights; fewer
        bytes per frame on simd and simd-openmp, within the error bound of
        docs/backends/quantized-rest.md). The encoding is part of the mesh's id.
        """
        requests = _requests.upload_requests(positions, joints, weights, normals,
                                             normalize_weights, joint_count,
                                             morph_targets, tangents, rest_encoding)
        info = self._upload(requests)
        self._meshes[info.mesh_id] = (requests, requests[0].header.joint_count,
                                      requests[0].header.vertex_count)
        return str(info.mesh_id)

    def _upload(self, requests: List[pb.UploadMeshRequest]) -> pb.MeshInfo:
        try:
            info: pb.MeshInfo = self._stub.UploadMesh(iter(requests),
                                                      timeout=self.upload_timeout)
            return info
        except grpc.RpcError as e:
            raise rpc_error(e) from None

    def _reupload(self, mesh_id: str, error: SkinserveError) -> None:
        if mesh_id not in self._meshes:
            raise error  # not uploaded through this client: nothing to send again
        self._upload(self._meshes[mesh_id][0])

    def _joint_count(self, mesh_id: str) -> Optional[int]:
        known = self._meshes.get(mesh_id)
        return known[1] if known else None

    def _vertex_count(self, mesh_id: str) -> int:
        if mesh_id in self._meshes:
            return self._meshes[mesh_id][2]
        try:
            info = self._stub.GetMesh(pb.GetMeshRequest(mesh_id=mesh_id), timeout=self.timeout)
        except grpc.RpcError as e:
            raise rpc_error(e) from None
        return int(info.vertex_count)

    # ---- shared memory (same host) ------------------------------------------------------
    def register_region(self, region: SharedMemoryRegion,
                        name: Optional[str] = None) -> pb.RegionInfo:
        """Registers a SharedMemoryRegion with the server (which must run on this host,
        with the region's directory as its --shm-dir, reached on its Unix socket) under
        `name` (default: its key). The region is this process's: frames naming it are
        skinned straight into it. Returns the server's RegionInfo."""
        name = name or region.key
        try:
            info: pb.RegionInfo = self._stub.RegisterRegion(pb.RegisterRegionRequest(
                name=name, key=region.key, byte_size=region.byte_size), timeout=self.timeout)
        except grpc.RpcError as e:
            raise rpc_error(e) from None
        region.name = name
        return info

    def unregister_region(self, region_or_name: Union[SharedMemoryRegion, str]) -> None:
        """Returns once the server has unmapped the region: it writes there no more."""
        region: Optional[SharedMemoryRegion] = None
        if isinstance(region_or_name, SharedMemoryRegion):
            region, name = region_or_name, region_or_name.name
        else:
            name = region_or_name
        try:
            self._stub.UnregisterRegion(pb.UnregisterRegionRequest(name=name),
                                        timeout=self.timeout)
        except grpc.RpcError as e:
            raise rpc_error(e) from None
        if region is not None:
            region.name = None

    def regions(self) -> List[Dict[str, Any]]:
        """This process's registered regions (the server shows each client its own): a list
        of dicts (name, key, byte_size, ...)."""
        try:
            response = self._stub.ListRegions(pb.ListRegionsRequest(), timeout=self.timeout)
        except grpc.RpcError as e:
            raise rpc_error(e) from None
        return _answers.regions(response)

    # ---- frames -------------------------------------------------------------------------
    @overload
    def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
             backend: Optional[str] = ..., want_normals: Literal[False] = ...,
             encoding: str = ..., frame: int = ..., region: Optional[SharedMemoryRegion] = ...,
             offset: int = ...,
             morph_weights: Optional[FrameWeights] = ...,
             want_tangents: Literal[False] = ...) -> FloatArray: ...

    @overload
    def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
             backend: Optional[str] = ..., *, want_normals: Literal[True],
             encoding: str = ..., frame: int = ..., region: Optional[SharedMemoryRegion] = ...,
             offset: int = ...,
             morph_weights: Optional[FrameWeights] = ...,
             want_tangents: Literal[False] = ...) -> Tuple[FloatArray, FloatArray]: ...

    @overload
    def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
             backend: Optional[str] = ..., *, want_normals: Literal[True],
             encoding: str = ..., frame: int = ..., region: Optional[SharedMemoryRegion] = ...,
             offset: int = ...,
             morph_weights: Optional[FrameWeights] = ...,
             want_tangents: Literal[True]) -> Tuple[FloatArray, FloatArray, FloatArray]: ...

    def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
             backend: Optional[str] = None, want_normals: bool = False,
             encoding: str = "float32", frame: int = 0,
             region: Optional[SharedMemoryRegion] = None, offset: int = 0,
             morph_weights: Optional[FrameWeights] = None,
             want_tangents: bool = False) -> Answer:
        """One frame: palette float32 (J, 3, 4) -> positions (V, 3) float32, or
        (positions, normals) with want_normals. A crowd, palettes (K, J, 3, 4) of K
        instances of the mesh, is one request and answers (K, V, 3) arrays.

        want_tangents (with want_normals, for a mesh uploaded with tangents): answers
        (positions, normals, tangents), tangents (V, 4) float32 x y z w ((K, V, 4) for a
        crowd), w exactly +1 or -1.

        encoding: how the server sends the vertices ("float32", "float16" or "snorm16",
        see docs/serving/encodings.md); the answer is decoded to float32.

        region: a registered SharedMemoryRegion: the server writes the frame into it from
        `offset` (a multiple of 64) and the answer views it: float32 arrays (float16 ones
        with encoding="float16"; snorm16 is decoded into new arrays), valid until the
        region's bytes are written again.

        morph_weights: the frame's morph target weights, sparse: {target: weight} (targets
        left out weigh 0), for every instance of a crowd; or a sequence of K such mappings,
        one per instance of a crowd of K >= 2."""
        crowd = _arrays.check_palette("palette", palette, self._joint_count(mesh_id))
        request = _requests.skin_request(mesh_id, palette, crowd, frame, backend, want_normals,
                                         encoding, region, offset, morph_weights, want_tangents)
        for attempt in range(self.max_reuploads + 1):
            result = Frame(crowd)
            try:
                for part in self._stub.Skin(request, timeout=self.timeout):
                    result.add_part(part, want_normals, region)
                return result.result(want_normals, want_tangents)
            except grpc.RpcError as e:
                error = rpc_error(e, frame)
                if e.code() != grpc.StatusCode.NOT_FOUND or attempt == self.max_reuploads:
                    raise error from None
                self._reupload(mesh_id, error)
        raise AssertionError("unreachable")

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[npt.NDArray[np.float32]],
               backend: Optional[str] = ..., want_normals: Literal[False] = ...,
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[False] = ...
               ) -> Iterator[FloatArray]: ...

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[npt.NDArray[np.float32]],
               backend: Optional[str] = ..., *, want_normals: Literal[True],
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[False] = ...
               ) -> Iterator[Tuple[FloatArray, FloatArray]]: ...

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[npt.NDArray[np.float32]],
               backend: Optional[str] = ..., *, want_normals: Literal[True],
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[True]
               ) -> Iterator[Tuple[FloatArray, FloatArray, FloatArray]]: ...

    def stream(self, mesh_id: str, palettes: Iterable[npt.NDArray[np.float32]],
               backend: Optional[str] = None, want_normals: bool = False,
               encoding: str = "float32", window: int = 8,
               region: Optional[SharedMemoryRegion] = None,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = None,
               want_tangents: bool = False
               ) -> Iterator[Answer]:
        """Frame after frame over one StreamSkin call: yields each frame's positions (or
        (positions, normals)) in order. `palettes`: a sequence of float32 (J, 3, 4)
        palettes (or an array (F, J, 3, 4)), all checked before the first is sent. A crowd
        frame is a (K, J, 3, 4) palette (an array (F, K, J, 3, 4) for F of them) and yields
        (K, V, 3) arrays.

        A frame answered NOT_FOUND re-uploads the mesh and the stream resumes from that
        frame; a stream that ends UNAVAILABLE (a replica draining or gone) resumes on a new
        stream (up to max_reconnects times); any other failed frame raises SkinserveError.

        region: a registered SharedMemoryRegion large enough for `window` frames: frame i is
        written into slot i % window and yielded as arrays that view it, valid until the
        next frame is taken (copy what you keep).

        morph_weights: one entry per palette, as skin's morph_weights (None: no weights).

        want_tangents: yields (positions, normals, tangents), as skin.
        """
        palettes = list(palettes)
        joints = self._joint_count(mesh_id)
        crowds = [_arrays.check_palette(f"palettes[{i}]", palette, joints)
                  for i, palette in enumerate(palettes)]
        _requests.check_window(window)
        _requests.check_encoding(encoding)
        weights = _requests.stream_weights(morph_weights, len(palettes))
        stride = 0
        if region is not None:
            stride = _requests.region_stride(self._vertex_count(mesh_id), crowds,
                                             want_normals, encoding, window, region,
                                             want_tangents)
        requests = [_requests.skin_request(mesh_id, p, k, i, backend, want_normals, encoding,
                                           region, (i % window) * stride, w, want_tangents)
                    for i, (p, k, w) in enumerate(zip(palettes, crowds, weights))]
        next_frame, reuploads, reconnects = 0, 0, 0
        while next_frame < len(requests):
            restart: Optional[SkinserveError] = None
            ended: List[Tuple[Any, str]] = []
            with contextlib.closing(self._one_stream(requests, next_frame, window,
                                                     want_normals, region, ended)) as answers:
                for index, frame in answers:
                    if frame.error is None:
                        next_frame = index + 1
                        yield frame.result(want_normals, want_tangents)
                        continue
                    code, message = frame.error
                    error = SkinserveError(code, message, index)
                    if code != grpc.StatusCode.NOT_FOUND or reuploads >= self.max_reuploads:
                        raise error
                    restart = error
                    break
            if restart is not None:  # resume from the frame that was NOT_FOUND
                reuploads += 1
                self._reupload(mesh_id, restart)
            elif next_frame < len(requests):  # the stream ended UNAVAILABLE or idle early
                reconnects += 1
                if reconnects > self.max_reconnects:
                    code, message = ended[0] if ended else (grpc.StatusCode.UNAVAILABLE, "")
                    raise SkinserveError(code, f"stream ended {reconnects} times, the last: "
                                         f"{message}", next_frame)

    def _one_stream(self, requests: List[pb.SkinRequest], first: int, window: int,
                    want_normals: bool, region: Optional[SharedMemoryRegion],
                    ended: List[Tuple[Any, str]],
                    make_frame: Optional[Callable[[int], Any]] = None
                    ) -> Generator[Tuple[int, Any], None, None]:
        """Sends requests[first:] with at most `window` unanswered; yields (index, Frame)
        in order. Ends early (without raising, the reason appended to `ended`) when the
        stream ends UNAVAILABLE or waits stream_idle_timeout for an answer. With a region, a
        frame's slot is reused only once the caller has taken the next frame. `make_frame`:
        the assembler of requests[i]'s answer (ticks: a TickAnswer), instead of a Frame."""
        credits = threading.Semaphore(window)
        stop = threading.Event()
        outbox: "queue.Queue[Optional[pb.SkinRequest]]" = queue.Queue()
        lock, in_flight = threading.Lock(), [0]
        watchdog: Optional[_IdleWatchdog] = None

        def send() -> None:
            for request in requests[first:]:
                while not credits.acquire(timeout=0.1):
                    if stop.is_set():
                        return
                if stop.is_set():
                    return
                outbox.put(request)
            outbox.put(None)

        def request_iterator() -> Iterator[pb.SkinRequest]:
            while True:
                request = outbox.get()
                if request is None:
                    return
                with lock:
                    in_flight[0] += 1
                    if watchdog is not None:
                        watchdog.awaiting(True)
                yield request

        call = self._stub.StreamSkin(request_iterator())
        watchdog = _IdleWatchdog(call, self.stream_idle_timeout)
        sender = threading.Thread(target=send, daemon=True)
        sender.start()

        def new_frame(i: int) -> Any:  # the frame answering requests[i]; past the end, one never filled
            if make_frame is not None:
                return make_frame(i)
            return Frame((requests[i].instances or None) if i < len(requests) else None)

        frame, index = new_frame(first), first
        try:
            for part in call:
                watchdog.answered()
                frame.add_part(part, want_normals, region)
                if part.last:
                    with lock:
                        in_flight[0] -= 1
                    if region is None:
                        credits.release()
                    watchdog.awaiting(False)  # the caller holds the frame: nothing is read
                    yield index, frame
                    with lock:
                        watchdog.awaiting(in_flight[0] > 0)
                    if region is not None:  # the caller is done with the frame's slot
                        credits.release()
                    index += 1
                    frame = new_frame(index)
        except grpc.RpcError as e:
            if watchdog.fired:
                ended.append((grpc.StatusCode.DEADLINE_EXCEEDED,
                              f"no answer for {self.stream_idle_timeout} s with frames in "
                              "flight (stream_idle_timeout)"))
            elif e.code() == grpc.StatusCode.UNAVAILABLE:
                ended.append((e.code(), e.details()))
            else:
                raise rpc_error(e, index) from None
        finally:
            watchdog.stop()
            stop.set()
            outbox.put(None)
            call.cancel()
            sender.join()

    # ---- ticks ----------------------------------------------------------------------------
    def tick(self, characters: Sequence[Character], frame: int = 0) -> List[CharacterResult]:
        """One tick: many characters (skinserve.Character each: mesh id, palette or crowd,
        and skin's options) skinned by one request, answered as one CharacterResult per
        character in order. A character whose input is bad fails alone: its result's
        `error` names it and the field, the others are answered. A character answered
        NOT_FOUND for a mesh this client uploaded has the mesh uploaded again and is sent
        again (in a tick of those characters). A tick refused whole raises SkinserveError."""
        characters = list(characters)
        crowds = _tick.check_characters(characters, self._joint_count)
        return self._tick_with_reuploads(characters, crowds, frame, 0)

    def _tick_with_reuploads(self, characters: List[Character], crowds: List[Optional[int]],
                             frame: int, slot_offset: int,
                             results: Optional[List[CharacterResult]] = None
                             ) -> List[CharacterResult]:
        if results is None:
            results = self._tick_once(characters, crowds, frame, slot_offset)
        for _ in range(self.max_reuploads):
            missing = _tick.not_found(characters, results, self._meshes)
            if not missing:
                break
            for mesh_id in {characters[i].mesh_id for i in missing}:
                self._upload(self._meshes[mesh_id][0])
            again = self._tick_once([characters[i] for i in missing],
                                    [crowds[i] for i in missing], frame, slot_offset)
            for i, result in zip(missing, again):
                result.index = i
                results[i] = result
        return results

    def _tick_once(self, characters: List[Character], crowds: List[Optional[int]],
                   frame: int, slot_offset: int) -> List[CharacterResult]:
        request = _tick.tick_request(characters, crowds, frame, slot_offset)
        answer = _tick.TickAnswer(characters, crowds, frame)
        try:
            for part in self._stub.Skin(request, timeout=self.timeout):
                answer.add_part(part)
        except grpc.RpcError as e:
            raise rpc_error(e, frame) from None
        return answer.answered()

    def stream_ticks(self, ticks: Iterable[Sequence[Character]],
                     window: int = 2) -> Iterator[List[CharacterResult]]:
        """Tick after tick over one StreamSkin call, at most `window` unanswered: yields each
        tick's results (as tick answers them) in order; tick i's frame number is i. A
        character answered NOT_FOUND for a mesh this client uploaded is uploaded again and
        sent again before its tick is yielded. Region characters: tick i writes each at its
        offset + (i % window) * the ticks' furthest range end (the region must hold `window`
        of those); the arrays view it until the next tick is taken. A tick refused whole, or
        a stream that ends (UNAVAILABLE, idle), raises SkinserveError."""
        tick_list = [list(t) for t in ticks]
        crowds = [_tick.check_characters(t, self._joint_count) for t in tick_list]
        _requests.check_window(window)
        stride, region = _tick.stream_regions(tick_list, crowds, self._vertex_count, window)
        requests = [_tick.tick_request(t, k, i, (i % window) * stride)
                    for i, (t, k) in enumerate(zip(tick_list, crowds))]

        def make(i: int) -> _tick.TickAnswer:
            if i >= len(tick_list):
                return _tick.TickAnswer([], [], i)
            return _tick.TickAnswer(tick_list[i], crowds[i], i)

        ended: List[Tuple[Any, str]] = []
        answered = 0
        with contextlib.closing(self._one_stream(requests, 0, window, False, region, ended,
                                                 make)) as answers:
            for index, answer in answers:
                results = self._tick_with_reuploads(tick_list[index], crowds[index], index,
                                                    (index % window) * stride,
                                                    answer.answered())
                answered = index + 1
                yield results
        if answered < len(tick_list):
            code, message = ended[0] if ended else (grpc.StatusCode.UNAVAILABLE, "")
            raise SkinserveError(code, f"stream of ticks ended: {message}", answered)

    # ---- the server ----------------------------------------------------------------------
    def backends(self) -> List[Dict[str, Any]]:
        """The server's backends: a list of dicts (id, description, available, ...)."""
        try:
            response = self._stub.ListBackends(pb.ListBackendsRequest(), timeout=self.timeout)
        except grpc.RpcError as e:
            raise rpc_error(e) from None
        return _answers.backends(response)

    def stats(self) -> Dict[str, Any]:
        """The server's counters: a dict, with "backends" a dict by backend id."""
        try:
            s = self._stub.GetServerStats(pb.GetServerStatsRequest(), timeout=self.timeout)
        except grpc.RpcError as e:
            raise rpc_error(e) from None
        return _answers.stats(s)
