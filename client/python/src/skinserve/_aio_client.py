"""AsyncClient: the blocking Client's methods for asyncio, over grpc.aio. The requests,
the frame assembly, the errors and the answers are the blocking client's own modules;
only the waiting differs (coroutines and an async generator instead of threads)."""
import asyncio
import time
from typing import (Any, AsyncGenerator, AsyncIterator, Callable, Dict, Iterable, List,
                    Literal, Optional, Sequence, Tuple, Union, overload)

import grpc
import grpc.aio
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


class AsyncClient(ClientCore):
    """skinserve.Client for asyncio: the same constructor arguments (target, TLS,
    timeouts, keepalive, max_reuploads, max_reconnects) and methods, as coroutines, and
    `stream` as an async generator. Create it inside a running event loop:

        async with skinserve.AsyncClient("127.0.0.1:50051") as client:
            mesh_id = await client.upload(positions, joints, weights)
            vertices = await client.skin(mesh_id, palette, encoding="float16")
            async for vertices in client.stream(mesh_id, palettes):
                ...

    Its behaviour is the blocking client's: NOT_FOUND re-uploads and resends, a stream that
    ends UNAVAILABLE or idle resumes on a new one, errors are SkinserveError.
    """

    _grpc = grpc.aio

    async def close(self) -> None:
        await self._channel.close()

    async def __aenter__(self) -> "AsyncClient":
        return self

    async def __aexit__(self, *exc: Any) -> None:
        await self.close()

    # ---- meshes -----------------------------------------------------------------------
    async def upload(self, positions: npt.NDArray[np.float32], joints: npt.NDArray[np.uint16],
                     weights: npt.NDArray[np.float32],
                     normals: Optional[npt.NDArray[np.float32]] = None,
                     normalize_weights: bool = False, joint_count: Optional[int] = None,
                     morph_targets: Optional[Sequence[MorphTarget]] = None,
                     tangents: Optional[npt.NDArray[np.float32]] = None,
                     rest_encoding: str = "float32") -> str:
        """Client.upload: stores a mesh (with its morph targets) and returns its id."""
        requests = _requests.upload_requests(positions, joints, weights, normals,
                                             normalize_weights, joint_count, morph_targets,
                                             tangents, rest_encoding)
        return self._remember(requests, await self._upload(requests))

    async def _upload(self, requests: List[pb.UploadMeshRequest]) -> pb.MeshInfo:
        try:
            info: pb.MeshInfo = await self._stub.UploadMesh(iter(requests),
                                                            timeout=self.upload_timeout)
            return info
        except grpc.RpcError as e:
            raise rpc_error(e) from None

    async def _vertex_count(self, mesh_id: str) -> int:
        known = self._known_vertex_count(mesh_id)
        if known is not None:
            return known
        return int((await self._unary(self._stub.GetMesh,
                                      pb.GetMeshRequest(mesh_id=mesh_id))).vertex_count)

    async def _unary(self, method: Any, request: Any) -> Any:
        try:
            return await method(request, timeout=self.timeout)
        except grpc.RpcError as e:
            raise rpc_error(e) from None

    # ---- shared memory (same host) ------------------------------------------------------
    async def register_region(self, region: SharedMemoryRegion,
                              name: Optional[str] = None) -> pb.RegionInfo:
        """Client.register_region."""
        name = name or region.key
        info: pb.RegionInfo = await self._unary(self._stub.RegisterRegion,
                                                pb.RegisterRegionRequest(
                                                    name=name, key=region.key,
                                                    byte_size=region.byte_size))
        region.name = name
        return info

    async def unregister_region(self, region_or_name: Union[SharedMemoryRegion, str]) -> None:
        """Client.unregister_region: returns once the server has unmapped the region."""
        region, name = self._region_and_name(region_or_name)
        await self._unary(self._stub.UnregisterRegion, pb.UnregisterRegionRequest(name=name))
        if region is not None:
            region.name = None

    async def regions(self) -> List[Dict[str, Any]]:
        """Client.regions."""
        return _answers.regions(await self._unary(self._stub.ListRegions,
                                                  pb.ListRegionsRequest()))

    # ---- frames -------------------------------------------------------------------------
    @overload
    async def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
                   backend: Optional[str] = ..., want_normals: Literal[False] = ...,
                   encoding: str = ..., frame: int = ...,
                   region: Optional[SharedMemoryRegion] = ..., offset: int = ...,
                   morph_weights: Optional[FrameWeights] = ...,
                   want_tangents: Literal[False] = ...) -> FloatArray: ...

    @overload
    async def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
                   backend: Optional[str] = ..., *, want_normals: Literal[True],
                   encoding: str = ..., frame: int = ...,
                   region: Optional[SharedMemoryRegion] = ..., offset: int = ...,
                   morph_weights: Optional[FrameWeights] = ...,
                   want_tangents: Literal[False] = ...
                   ) -> Tuple[FloatArray, FloatArray]: ...

    @overload
    async def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
                   backend: Optional[str] = ..., *, want_normals: Literal[True],
                   encoding: str = ..., frame: int = ...,
                   region: Optional[SharedMemoryRegion] = ..., offset: int = ...,
                   morph_weights: Optional[FrameWeights] = ...,
                   want_tangents: Literal[True]
                   ) -> Tuple[FloatArray, FloatArray, FloatArray]: ...

    async def skin(self, mesh_id: str, palette: npt.NDArray[np.float32],
                   backend: Optional[str] = None, want_normals: bool = False,
                   encoding: str = "float32", frame: int = 0,
                   region: Optional[SharedMemoryRegion] = None, offset: int = 0,
                   morph_weights: Optional[FrameWeights] = None,
                   want_tangents: bool = False) -> Answer:
        """Client.skin: one frame, a single palette (J, 3, 4) or a crowd (K, J, 3, 4),
        with its morph weights ({target: weight}, or one such per crowd instance);
        want_tangents answers (positions, normals, tangents)."""
        crowd, request = self._skin_request(mesh_id, palette, backend, want_normals, encoding,
                                            frame, region, offset, morph_weights, want_tangents)
        return await self._skin_call(request, crowd, region, want_normals, want_tangents)

    async def _skin_call(self, request: pb.SkinRequest, crowd: Optional[int],
                   region: Optional[SharedMemoryRegion], want_normals: bool,
                   want_tangents: bool) -> Answer:
        """One Skin call and its answer; a mesh the server lost is uploaded again and the
        frame sent again, up to max_reuploads times (skin and skin_pose share it)."""
        for attempt in range(self.max_reuploads + 1):
            result = Frame(crowd)
            try:
                async for part in self._stub.Skin(request, timeout=self.timeout):
                    result.add_part(part, want_normals, region)
                return result.result(want_normals, want_tangents)
            except grpc.RpcError as e:
                await self._reupload(self._retry_frame(e, attempt, request.frame,
                                                       request.mesh_id))
        raise AssertionError("unreachable")

    async def _reupload(self, lost: Lost) -> None:
        """Client._reupload: the mesh, skeleton (with its clips) or clip a NOT_FOUND named."""
        if lost.kind == "mesh":
            await self._upload(self._meshes[lost.id][0])
            return
        if lost.kind == "clip":
            request = self._clips[lost.id]
            try:
                await self._unary(self._stub.UploadClip, request)
                return
            except SkinserveError as e:
                if e.code != grpc.StatusCode.NOT_FOUND:
                    raise
            lost = Lost("skeleton", request.skeleton_id)
        skeleton, *clips = self._skeleton_uploads(lost.id)
        await self._unary(self._stub.UploadSkeleton, skeleton)
        for clip in clips:
            await self._unary(self._stub.UploadClip, clip)

    # ---- animation on the server (docs/serving/animation.md) ---------------------------
    async def upload_skeleton(self, parents: npt.NDArray[np.int16],
                              rest: npt.NDArray[np.float32],
                              palette_joints: npt.NDArray[np.uint16],
                              inverse_bind: npt.NDArray[np.float32],
                              names: Optional[Sequence[str]] = None) -> str:
        """Client.upload_skeleton."""
        request = _pose.skeleton_request(parents, rest, palette_joints, inverse_bind, names)
        return self._remember_skeleton(
            request, str((await self._unary(self._stub.UploadSkeleton, request)).skeleton_id))

    async def upload_clip(self, skeleton_id: str, tracks: Sequence[ClipTrack], name: str = "",
                          duration: float = 0.0, max_error_mm: float = 0.0) -> pb.ClipInfo:
        """Client.upload_clip."""
        request = _pose.clip_request(skeleton_id, tracks, name, duration, max_error_mm)
        return self._remember_clip(request, await self._unary(self._stub.UploadClip, request))

    async def delete_clip(self, clip_id: str) -> bool:
        """Client.delete_clip."""
        self._forget_clip(clip_id)
        return bool((await self._unary(self._stub.DeleteClip,
                                       pb.DeleteClipRequest(clip_id=clip_id))).deleted)

    async def skin_pose(self, mesh_id: str, pose: Pose, backend: Optional[str] = None,
                        want_normals: bool = False, encoding: str = "float32",
                        frame: int = 0) -> Answer:
        """Client.skin_pose."""
        request = _pose.pose_request(mesh_id, pose, frame, backend, want_normals, encoding)
        return await self._skin_call(request, None, None, want_normals, False)

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[PaletteOrPose],
               backend: Optional[str] = ..., want_normals: Literal[False] = ...,
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[False] = ...
               ) -> AsyncIterator[FloatArray]: ...

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[PaletteOrPose],
               backend: Optional[str] = ..., *, want_normals: Literal[True],
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[False] = ...
               ) -> AsyncIterator[Tuple[FloatArray, FloatArray]]: ...

    @overload
    def stream(self, mesh_id: str, palettes: Iterable[PaletteOrPose],
               backend: Optional[str] = ..., *, want_normals: Literal[True],
               encoding: str = ..., window: int = ...,
               region: Optional[SharedMemoryRegion] = ...,
               morph_weights: Optional[Iterable[Optional[FrameWeights]]] = ...,
               want_tangents: Literal[True]
               ) -> AsyncIterator[Tuple[FloatArray, FloatArray, FloatArray]]: ...

    async def stream(self, mesh_id: str, palettes: Iterable[PaletteOrPose],
                     backend: Optional[str] = None, want_normals: bool = False,
                     encoding: str = "float32", window: int = 8,
                     region: Optional[SharedMemoryRegion] = None,
                     morph_weights: Optional[Iterable[Optional[FrameWeights]]] = None,
                     want_tangents: bool = False
                     ) -> AsyncIterator[Answer]:
        """Client.stream as an async generator: frame after frame over one StreamSkin call,
        at most `window` unanswered, yielded in order. To stop early, close it
        (`async with contextlib.aclosing(client.stream(...)) as frames:`): that cancels the
        call at once, rather than when the generator is collected."""
        frames = FrameStream(self, mesh_id, palettes, backend, want_normals, encoding, window,
                             region, morph_weights, want_tangents)
        frames.build(await self._vertex_count(mesh_id) if region is not None else 0)
        while not frames.done:
            ended = frames.open()
            answers = self._one_stream(frames.requests, frames.next_frame, window, want_normals,
                                       region, ended)
            try:
                async for index, frame in answers:
                    answer = frames.answer(index, frame)
                    if answer is None:
                        break  # NOT_FOUND: upload the mesh again and resume from the frame
                    yield answer
            finally:
                await answers.aclose()
            again = frames.closed()
            if again is not None:
                await self._reupload(again)

    async def _one_stream(self, requests: List[pb.SkinRequest], first: int, window: int,
                          want_normals: bool, region: Optional[SharedMemoryRegion],
                          ended: List[Tuple[Any, str]],
                          make_frame: Optional[Callable[[int], Any]] = None
                          ) -> AsyncGenerator[Tuple[int, Any], None]:
        """Client._one_stream with a writer task instead of a thread: sends requests[first:]
        with at most `window` unanswered and yields (index, Frame) in order (or what
        `make_frame(index)` makes: ticks); ends early (the reason appended to `ended`) on
        UNAVAILABLE or after stream_idle_timeout seconds without an answer while frames are
        in flight."""
        credits = asyncio.Semaphore(window)
        call = self._stub.StreamSkin()
        in_flight = 0
        waiting_since = time.monotonic()  # the last answer, or when frames went in flight

        async def send() -> None:
            nonlocal in_flight, waiting_since
            for request in requests[first:]:
                await credits.acquire()
                if in_flight == 0:
                    waiting_since = time.monotonic()
                in_flight += 1
                await call.write(request)
            await call.done_writing()

        async def read() -> Any:
            """The next part, grpc.aio.EOF at the end, or None when the stream was idle too
            long with frames in flight (then the call is cancelled)."""
            limit = self.stream_idle_timeout
            reading = asyncio.ensure_future(call.read())
            while limit:
                done, _ = await asyncio.wait({reading}, timeout=limit)
                if done:
                    break
                if in_flight > 0 and time.monotonic() - waiting_since >= limit:
                    reading.cancel()
                    call.cancel()
                    return None
            return await reading

        new_frame = _core.new_frame(requests, make_frame)
        sender = asyncio.ensure_future(send())
        frame, index = new_frame(first), first
        try:
            while True:
                part = await read()
                if part is None:
                    ended.append(self._stream_idle_ended())
                    return
                if part is grpc.aio.EOF:
                    return
                waiting_since = time.monotonic()
                frame.add_part(part, want_normals, region)
                if part.last:
                    in_flight -= 1
                    if region is None:
                        credits.release()
                    yield index, frame
                    waiting_since = time.monotonic()  # the caller's time is not the server's
                    if region is not None:  # the caller is done with the frame's slot
                        credits.release()
                    index += 1
                    frame = new_frame(index)
        except grpc.RpcError as e:
            if e.code() == grpc.StatusCode.UNAVAILABLE:
                ended.append((e.code(), e.details()))
            else:
                raise rpc_error(e, index) from None
        finally:
            call.cancel()
            sender.cancel()
            try:
                await sender
            except (asyncio.CancelledError, grpc.RpcError, asyncio.InvalidStateError):
                pass  # the call ended first: its status is what counts, handled above

    # ---- ticks ----------------------------------------------------------------------------
    async def tick(self, characters: Sequence[Character],
                   frame: int = 0) -> List[CharacterResult]:
        """Client.tick: many characters in one request, one CharacterResult each (a bad
        character fails alone, its error naming it); NOT_FOUND re-uploads and resends."""
        characters = list(characters)
        crowds = _tick.check_characters(characters, self._joint_count)
        return await self._tick_with_reuploads(characters, crowds, frame, 0)

    async def _tick_with_reuploads(self, characters: List[Character],
                                   crowds: List[Optional[int]], frame: int, slot_offset: int,
                                   results: Optional[List[CharacterResult]] = None
                                   ) -> List[CharacterResult]:
        if results is None:
            results = await self._tick_once(characters, crowds, frame, slot_offset)
        for _ in range(self.max_reuploads):
            missing, lost = self._tick_reuploads(characters, results)
            if not missing:
                break
            for what in lost:
                await self._reupload(what)
            again = await self._tick_once([characters[i] for i in missing],
                                          [crowds[i] for i in missing], frame, slot_offset)
            _core.merge_tick_results(results, missing, again)
        return results

    async def _tick_once(self, characters: List[Character], crowds: List[Optional[int]],
                         frame: int, slot_offset: int) -> List[CharacterResult]:
        request = _tick.tick_request(characters, crowds, frame, slot_offset)
        answer = _tick.TickAnswer(characters, crowds, frame)
        try:
            async for part in self._stub.Skin(request, timeout=self.timeout):
                answer.add_part(part)
        except grpc.RpcError as e:
            raise rpc_error(e, frame) from None
        return answer.answered()

    async def stream_ticks(self, ticks: Iterable[Sequence[Character]],
                           window: int = 2) -> AsyncIterator[List[CharacterResult]]:
        """Client.stream_ticks as an async generator: tick after tick over one StreamSkin
        call, at most `window` unanswered, each tick's results yielded in order."""
        plan = TickStream(self, ticks, window)
        plan.build({m: await self._vertex_count(m) for m in plan.region_meshes()})
        answered = 0
        answers = self._one_stream(plan.requests, 0, window, False, plan.region, plan.ended,
                                   plan.make_answer)
        try:
            async for index, answer in answers:
                results = await self._tick_with_reuploads(plan.ticks[index], plan.crowds[index],
                                                          index, plan.slot_offset(index),
                                                          answer.answered())
                answered = index + 1
                yield results
        finally:
            await answers.aclose()
        plan.check_finished(answered)

    # ---- the server ----------------------------------------------------------------------
    async def backends(self) -> List[Dict[str, Any]]:
        """Client.backends."""
        return _answers.backends(await self._unary(self._stub.ListBackends,
                                                   pb.ListBackendsRequest()))

    async def stats(self) -> Dict[str, Any]:
        """Client.stats."""
        return _answers.stats(await self._unary(self._stub.GetServerStats,
                                                pb.GetServerStatsRequest()))
