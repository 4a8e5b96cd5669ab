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

from . import _answers, _core, _pose, _requests, _tick
from ._core import ClientCore, FrameStream, TickStream
from ._errors import SkinserveError, rpc_error
from ._frame import Answer, FloatArray, Frame
from ._lost_upload import Lost
from ._morph import FrameWeights, MorphTarget
from ._pose import ClipTrack, PaletteOrPose, Pose
from ._shared_memory import SharedMemoryRegion
from ._tick import Character, CharacterResult
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


class Client(ClientCore):
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

    Meshes, skeletons and clips uploaded through this client are remembered: a frame
    answered NOT_FOUND (the replica evicted the mesh, or the call landed on another
    replica) uploads the mesh again, or the skeleton or clip of its pose that the error
    names, and resends the frame, as the C++ client library does.

    skinserve.AsyncClient has the same methods for asyncio.
    """

    _grpc = grpc

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
        return self._remember(requests, self._upload(requests))

    def _upload(self, requests: List[pb.UploadMeshRequest]) -> pb.MeshInfo:
        try:
            info: pb.MeshInfo = self._stub.UploadMesh(iter(requests),
                                                      timeout=self.upload_timeout)
            return info
        except grpc.RpcError as e:
            raise rpc_error(e) from None

    def _vertex_count(self, mesh_id: str) -> int:
        known = self._known_vertex_count(mesh_id)
        if known is not None:
            return known
        return int(self._unary(self._stub.GetMesh,
                               pb.GetMeshRequest(mesh_id=mesh_id)).vertex_count)

    def _unary(self, method: Any, request: Any) -> Any:
        try:
            return method(request, timeout=self.timeout)
        except grpc.RpcError as e:
            raise rpc_error(e) from None

    # ---- shared memory (same host) ------------------------------------------------------
    def register_region(self, region: SharedMemoryRegion,
                        name: Optional[str] = None) -> pb.RegionInfo:
        """Registers a SharedMemoryRegion with the server (which must run on this host,
        with the region's directory as its --shm-dir, reached on its Unix socket) under
        `name` (default: its key). The region is this process's: frames naming it are
        skinned straight into it. Returns the server's RegionInfo."""
        name = name or region.key
        info: pb.RegionInfo = self._unary(self._stub.RegisterRegion, pb.RegisterRegionRequest(
            name=name, key=region.key, byte_size=region.byte_size))
        region.name = name
        return info

    def unregister_region(self, region_or_name: Union[SharedMemoryRegion, str]) -> None:
        """Returns once the server has unmapped the region: it writes there no more."""
        region, name = self._region_and_name(region_or_name)
        self._unary(self._stub.UnregisterRegion, pb.UnregisterRegionRequest(name=name))
        if region is not None:
            region.name = None

    def regions(self) -> List[Dict[str, Any]]:
        """This process's registered regions (the server shows each client its own): a list
        of dicts (name, key, byte_size, ...)."""
        return _answers.regions(self._unary(self._stub.ListRegions, pb.ListRegionsRequest()))

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
        crowd, request = self._skin_request(mesh_id, palette, backend, want_normals, encoding,
                                            frame, region, offset, morph_weights, want_tangents)
        return self._skin_call(request, crowd, region, want_normals, want_tangents)

    def _skin_call(self, request: pb.SkinRequest, crowd: Optional[int],
                   region: Optional[SharedMemoryRegion], want_normals: bool,
                   want_tangents: bool) -> Answer:
        """One Skin call and its answer; a mesh the server lost is uploaded again and the
        frame sent again, up to max_reuploads times (skin and skin_pose share it)."""
        for attempt in range(self.max_reuploads + 1):
            result = Frame(crowd)
            try:
                for part in self._stub.Skin(request, timeout=self.timeout):
                    result.add_part(part, want_normals, region)
                return result.result(want_normals, want_tangents)
            except grpc.RpcError as e:
                self._reupload(self._retry_frame(e, attempt, request.frame, request.mesh_id))
        raise AssertionError("unreachable")

    def _reupload(self, lost: Lost) -> None:
        """Uploads again what a NOT_FOUND frame named (as the C++ SkinClient::Reupload): the
        mesh; a skeleton with the clips of it this client uploaded; a clip, or its skeleton
        (with its clips) when the server lost that too."""
        if lost.kind == "mesh":
            self._upload(self._meshes[lost.id][0])
            return
        if lost.kind == "clip":
            request = self._clips[lost.id]
            try:
                self._unary(self._stub.UploadClip, request)
                return
            except SkinserveError as e:
                if e.code != grpc.StatusCode.NOT_FOUND:
                    raise
            lost = Lost("skeleton", request.skeleton_id)
        skeleton, *clips = self._skeleton_uploads(lost.id)
        self._unary(self._stub.UploadSkeleton, skeleton)
        for clip in clips:
            self._unary(self._stub.UploadClip, clip)

    # ---- animation on the server (docs/serving/animation.md) ---------------------------
    def upload_skeleton(self, parents: npt.NDArray[np.int16], rest: npt.NDArray[np.float32],
                        palette_joints: npt.NDArray[np.uint16],
                        inverse_bind: npt.NDArray[np.float32],
                        names: Optional[Sequence[str]] = None) -> str:
        """A skeleton (see skinserve.skeleton_request); returns its skeleton_id."""
        request = _pose.skeleton_request(parents, rest, palette_joints, inverse_bind, names)
        return self._remember_skeleton(
            request, str(self._unary(self._stub.UploadSkeleton, request).skeleton_id))

    def upload_clip(self, skeleton_id: str, tracks: Sequence[ClipTrack], name: str = "",
                    duration: float = 0.0, max_error_mm: float = 0.0) -> pb.ClipInfo:
        """A clip for a stored skeleton; its ClipInfo (clip_id, bytes stored against
        raw_bytes, max_error_mm). max_error_mm: the error it is stored to (0: the server's
        default, 0.01 mm; else 0.01 to 10); a looser bound stores fewer bytes."""
        request = _pose.clip_request(skeleton_id, tracks, name, duration, max_error_mm)
        return self._remember_clip(request, self._unary(self._stub.UploadClip, request))

    def delete_clip(self, clip_id: str) -> bool:
        """Deletes a stored clip (True when it was there); this client forgets it, never
        to upload it again."""
        self._forget_clip(clip_id)
        return bool(self._unary(self._stub.DeleteClip,
                                pb.DeleteClipRequest(clip_id=clip_id)).deleted)

    def skin_pose(self, mesh_id: str, pose: Pose, backend: Optional[str] = None,
                  want_normals: bool = False, encoding: str = "float32",
                  frame: int = 0) -> Answer:
        """One frame whose palette the server computes from `pose`: positions (V, 3), or
        (positions, normals) with want_normals."""
        request = _pose.pose_request(mesh_id, pose, frame, backend, want_normals, encoding)
        return self._skin_call(request, None, None, want_normals, False)

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[PaletteOrPose],
               backend: Optional[str] = ..., want_normals: Literal[False] = ...,
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[False] = ...
               ) -> Iterator[FloatArray]: ...

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[PaletteOrPose],
               backend: Optional[str] = ..., *, want_normals: Literal[True],
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[False] = ...
               ) -> Iterator[Tuple[FloatArray, FloatArray]]: ...

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[PaletteOrPose],
               backend: Optional[str] = ..., *, want_normals: Literal[True],
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[True]
               ) -> Iterator[Tuple[FloatArray, FloatArray, FloatArray]]: ...

    def stream(self, mesh_id: str, palettes: Iterable[PaletteOrPose],
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
        (K, V, 3) arrays. An entry may be a skinserve.Pose instead: that frame carries the
        pose and the server computes its palette (as skin_pose); poses and palettes mix.

        A frame answered NOT_FOUND re-uploads the mesh and the stream resumes from that
        frame; a stream that ends UNAVAILABLE (a replica draining or gone) resumes on a new
        stream (up to max_reconnects times); any other failed frame raises SkinserveError.

        region: a registered SharedMemoryRegion large enough for `window` frames: frame i is
        written into slot i % window and yielded as arrays that view it, valid until the
        next frame is taken (copy what you keep).

        morph_weights: one entry per palette, as skin's morph_weights (None: no weights).

        want_tangents: yields (positions, normals, tangents), as skin.
        """
        frames = FrameStream(self, mesh_id, palettes, backend, want_normals, encoding, window,
                             region, morph_weights, want_tangents)
        frames.build(self._vertex_count(mesh_id) if region is not None else 0)
        while not frames.done:
            ended = frames.open()
            with contextlib.closing(self._one_stream(frames.requests, frames.next_frame, window,
                                                     want_normals, region, ended)) as answers:
                for index, frame in answers:
                    answer = frames.answer(index, frame)
                    if answer is None:
                        break  # NOT_FOUND: upload the mesh again and resume from the frame
                    yield answer
            again = frames.closed()
            if again is not None:
                self._reupload(again)

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

        new_frame = _core.new_frame(requests, make_frame)
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
                ended.append(self._stream_idle_ended())
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
        """One tick: many characters (skinserve.Character each: mesh id, palette, crowd or
        pose, and skin's options) skinned by one request, answered as one CharacterResult per
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
            missing, lost = self._tick_reuploads(characters, results)
            if not missing:
                break
            for what in lost:
                self._reupload(what)
            again = self._tick_once([characters[i] for i in missing],
                                    [crowds[i] for i in missing], frame, slot_offset)
            _core.merge_tick_results(results, missing, again)
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
        plan = TickStream(self, ticks, window)
        plan.build({m: self._vertex_count(m) for m in plan.region_meshes()})
        answered = 0
        with contextlib.closing(self._one_stream(plan.requests, 0, window, False,
                                                 plan.region, plan.ended,
                                                 plan.make_answer)) as answers:
            for index, answer in answers:
                results = self._tick_with_reuploads(plan.ticks[index], plan.crowds[index], index,
                                                    plan.slot_offset(index), answer.answered())
                answered = index + 1
                yield results
        plan.check_finished(answered)

    # ---- the server ----------------------------------------------------------------------
    def backends(self) -> List[Dict[str, Any]]:
        """The server's backends: a list of dicts (id, description, available, ...)."""
        return _answers.backends(self._unary(self._stub.ListBackends, pb.ListBackendsRequest()))

    def stats(self) -> Dict[str, Any]:
        """The server's counters: a dict, with "backends" a dict by backend id."""
        return _answers.stats(self._unary(self._stub.GetServerStats,
                                          pb.GetServerStatsRequest()))
